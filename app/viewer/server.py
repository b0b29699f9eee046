"""The 3-D viewer: one viser server, one comparison scene per browser tab.

The Compare page embeds ``http://HOST:PORT/?websocket=ws://HOST:PORT/bioplan/<kind>/<id>`` in
an iframe. When a tab connects, this module finds out which comparison it wants and builds that
tab's own scene (``client.scene``), GUI (play, pause, speed, scrub, layout, the phase of the
moment, the power curve in uPlot) and playback clock. So two tabs can show two comparisons at
once. One ``Player`` thread advances every playing tab.

Which comparison a tab wants, and whether it may see it (``app.viewer.access``): the Compare
page's iframe address carries the websocket path ``/bioplan/<kind>/<id>?token=...&methods=a,b``
with a capability the API issued for that comparison. viser 1.1 has no public API for a
client's URL, so the handshake's path and ``Origin`` are read from viser's private connection
table (``_handshake`` below) right after the handshake, before anything is sent; a connection
without a valid capability, from a foreign origin, or beyond the connection bounds is closed
there (code 1008) and gets no scene. ``tests/viewer/test_viewer_security.py`` connects real
websockets and fails, naming ``_handshake``, if a viser upgrade moves that table; until then
every tab is refused (the check fails closed).

viser takes the next free port when the one asked for is busy: ``start()`` returns the real
port and ``url`` reports it.
"""

from __future__ import annotations

import contextlib
import logging
import sys
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import quote

from app.errors import without_paths
from app.viewer._text import markdown_text
from app.viewer.access import Grant, Refused, ViewerAccess
from app.viewer.comparison import (
    LABELS,
    PHASES,
    Comparison,
    trajectory_colour,
    trajectory_label,
)
from app.viewer.framing import FOV
from app.viewer.playback import SPEEDS, PlaybackClock, Player, TickStats
from app.viewer.plots import power_plot
from app.viewer.scene import (
    COLORS,
    ComparisonScene,
    Layout,
    PreparedComparison,
    configure_lighting,
    no_human_text,
    slot_name,
)

logger = logging.getLogger(__name__)

#: ``(kind, id) -> PreparedComparison``; a front's also takes ``("quintic", point id)``.
Prepare = Callable[..., PreparedComparison]

#: Seconds between updates of the time slider and the plot's cursor while playing. Each update
#: re-renders viser's control panel; at 10 Hz that cost a software-rendered canvas about a third
#: of its frames, at 4 Hz about a seventh.
GUI_PERIOD = 0.25
_LAYOUT_NAMES: dict[str, Layout] = {"side by side": "side_by_side", "ghost overlay": "ghost"}
_SPEED_NAMES = {f"{s:g}x": s for s in SPEEDS}


def _handshake(server: Any, client_id: int) -> tuple[str, str | None] | None:
    """The request path and ``Origin`` of a client's websocket handshake, or None when they
    cannot be read.

    Private viser internals (viser 1.1 keeps each live ``websockets`` connection by client id);
    see the module docstring.
    """
    try:
        request = server._websock_server._live_connections[client_id].request
        return str(request.path), request.headers.get("Origin")
    except (AttributeError, KeyError, TypeError):
        return None


@dataclass
class ViewerSession:
    """One browser tab showing one comparison."""

    client: Any
    kind: str
    id: int
    scene: ComparisonScene
    clock: PlaybackClock
    gui: dict[str, Any]
    stats: TickStats = field(default_factory=TickStats)
    last_gui: float = 0.0
    phase_text: str = ""
    lock: threading.Lock = field(default_factory=threading.Lock)
    dirty: bool = True
    panel_minimised: bool = False

    @property
    def comparison(self) -> Comparison:
        return self.scene.prepared.comparison

    def tick(self) -> None:
        """Pose the robots for the clock's time; the panel's phase with the pose (one source,
        ``scene.phases_now``, which the labels show too), the slider and plot at most every
        GUI_PERIOD."""
        with self.lock:
            t = self.clock.time()
            index = self.comparison.index_at(t)
            moved = index != self.scene.index
            if moved or self.dirty:
                with self.client.atomic():
                    self.scene.show(index)
                    self._show_phase()
                self.stats.frame()
            now = time.monotonic()
            if self.dirty or (moved and now - self.last_gui >= GUI_PERIOD):
                self._refresh_gui(t)
                self.last_gui = now
                self.dirty = False

    def _show_phase(self) -> None:
        """The panel's phase text from the phases the scene's labels show (sent only when it
        changes, at a phase boundary: never a frame behind the labels)."""
        text = _phase_text(self.scene.phases_now, self.scene.shown)
        if text != self.phase_text:
            self.phase_text = text
            self.gui["phase"].content = text

    def _refresh_gui(self, t: float) -> None:
        slider = self.gui["time"]
        slider.value = round(min(t, float(slider.max)), 3)
        self.gui["plot"].data = power_plot(self.comparison, t, labels=self._plotted())

    def _plotted(self) -> tuple[str, str]:
        return self.scene.shown["standard"], self.scene.shown["optimized"]

    def toggle(self) -> None:
        with self.lock:
            if self.clock.playing:
                self.clock.pause()
            else:
                self.clock.play()
            button = self.gui["play"]
            button.label = "Pause" if self.clock.playing else "Play"
            button.icon = "player-pause" if self.clock.playing else "player-play"
            self.dirty = True

    def seek(self, t: float) -> None:
        with self.lock:
            self.clock.seek(t)
            self.dirty = True

    def set_speed(self, speed: float) -> None:
        with self.lock:
            self.clock.set_speed(speed)

    def set_layout(self, layout: Layout) -> None:
        with self.lock, self.client.atomic():
            self.scene.set_layout(layout)
            frame_client(self.client, self.scene)

    def set_methods(self, solid: str, ghost: str) -> None:
        """Show trajectory ``solid`` on the solid robot and ``ghost`` on the ghost."""
        with self.lock:
            with self.client.atomic():
                self.scene.set_methods(solid, ghost)
            self.gui["plot"].series = _plot_series(self._plotted())
            self.dirty = True

    def describe(self) -> dict[str, Any]:
        return {
            "client_id": int(self.client.client_id),
            "kind": self.kind,
            "id": self.id,
            "playing": self.clock.playing,
            "time": self.clock.time(),
            "speed": self.clock.speed,
            "layout": self.scene.layout,
            "solid": self.scene.shown["standard"],
            "ghost": self.scene.shown["optimized"],
            "human": self.scene.human is not None,
            "panel_minimised": self.panel_minimised,
            "phases": dict(self.scene.phases_now),
            "frames": self.stats.frames,
            "fps": self.stats.fps(),
        }


def _phase_text(phases: dict[str, str], shown: dict[str, str]) -> str:
    """The phase of the moment of each robot (named by its trajectory) and of the human."""
    lines = [
        f"{slot_name(slot, shown[slot])}: **{phases[slot]}** ({PHASES[phases[slot]]})"
        for slot in LABELS
    ]
    if "human" in phases:
        lines.append(f"recorded human: **{phases['human']}** ({PHASES[phases['human']]})")
    return "  \n".join(lines)


class ViewerServer:
    """A viser server that shows each tab the comparison its URL names.

    Args:
        prepare: ``(kind, id) -> PreparedComparison`` (e.g. a ``PreparedCache`` over the
            service's database).
        host: interface to bind (loopback by default: viser has no authentication).
        port: port to ask for; viser moves to the next free one when it is busy.
        fps: playback updates per second.
        autoplay: start playing as soon as a tab connects.
        access: capabilities and connection bounds (default: ``ViewerAccess()``).
        origin_hosts: host names the viewer's page may be loaded from besides the loopback
            names and ``host`` (``BIOPLAN_ALLOWED_HOSTS``); with a wildcard ``host`` and none,
            any name at the viewer's port.
    """

    def __init__(
        self,
        prepare: Prepare,
        *,
        host: str = "127.0.0.1",
        port: int = 8080,
        fps: float = 60.0,
        autoplay: bool = True,
        access: ViewerAccess | None = None,
        origin_hosts: Iterable[str] = (),
    ) -> None:
        self.prepare = prepare
        self.host = host
        self.requested_port = port
        self.autoplay = autoplay
        self.player = Player(fps)
        self.access = access or ViewerAccess()
        extra = {h.strip("[]").lower() for h in origin_hosts}
        self._any_origin_host = host in ("0.0.0.0", "::", "") and not extra
        self._origin_hosts = {"127.0.0.1", "localhost", "::1", host.strip("[]").lower()} | extra
        self._server: Any = None
        self._sessions: dict[int, ViewerSession] = {}
        self._grants: dict[int, Grant] = {}
        self._lock = threading.Lock()

    # lifecycle ---------------------------------------------------------------------------

    def start(self) -> int:
        """Start serving; returns the port actually bound."""
        import viser

        if self._server is not None:
            return self.port
        # viser prints a banner on stdout whatever ``verbose`` says; stdout is the CLI's (the
        # ``--json`` of ``bioplan serve`` is one object there).
        with contextlib.redirect_stdout(sys.stderr):
            server = viser.ViserServer(
                host=self.host, port=self.requested_port, label="BioPlan viewer", verbose=False
            )
        server.gui.configure_theme(
            control_layout="floating",
            control_width="medium",
            show_logo=False,
            show_share_button=False,
            brand_color=COLORS["standard"],
        )
        server.scene.set_up_direction("+z")
        configure_lighting(server.scene)
        # Checked right after the handshake, before viser sends anything (its own connect
        # callbacks run later, after the first camera message).
        server._websock_server.on_client_connect(self._admit)
        server._websock_server.on_client_disconnect(self._release)
        server.on_client_connect(self._on_connect)
        server.on_client_disconnect(self._on_disconnect)
        self._server = server
        self.player.start()
        port = self.port
        if port != self.requested_port:
            logger.warning("viewer port %d was busy; viser took %d", self.requested_port, port)
        return port

    def stop(self) -> None:
        self.player.stop()
        if self._server is not None:
            with contextlib.redirect_stdout(sys.stderr):
                self._server.stop()
            self._server = None
        with self._lock:
            self._sessions.clear()

    @property
    def running(self) -> bool:
        return self._server is not None

    @property
    def port(self) -> int:
        if self._server is None:
            raise RuntimeError("the viewer is not running")
        return int(self._server.get_port())

    @property
    def url(self) -> str:
        return f"http://{_url_host(self.host)}:{self.port}"

    def client_url(self, kind: str, result_id: int, methods: tuple[str, str] | None = None) -> str:
        """The iframe address that shows comparison ``kind``/``result_id``, with ``methods``
        (solid, ghost) on the two robots (None: the comparison's default pair), and a
        capability for that comparison only (``app.viewer.access``)."""
        # The websocket address is itself a query value of the page's address: percent-encoded
        # so that the viewer page passes its own query (token, methods) on whole.
        websocket = quote(self.websocket_url(kind, result_id, methods), safe="")
        return f"{self.url}/?websocket={websocket}&hideViserLogo"

    def websocket_url(
        self, kind: str, result_id: int, methods: tuple[str, str] | None = None
    ) -> str:
        """The websocket address of a comparison's tab, with a fresh capability."""
        token = self.access.issue(kind, int(result_id))
        query = f"token={token}" + (
            "" if methods is None else f"&methods={methods[0]},{methods[1]}"
        )
        return f"ws://{_url_host(self.host)}:{self.port}/bioplan/{kind}/{int(result_id)}?{query}"

    def sessions(self) -> list[dict[str, Any]]:
        with self._lock:
            sessions = list(self._sessions.values())
        return [s.describe() for s in sessions]

    # clients -----------------------------------------------------------------------------

    def _origin_ok(self, origin: str) -> bool:
        """Whether a browser's ``Origin`` is the viewer's own page (the iframe's document)."""
        scheme, _, rest = origin.strip().lower().partition("://")
        host, _, port = rest.rstrip("/").rpartition(":")
        if scheme not in ("http", "https") or port != str(self.port):
            return False
        return self._any_origin_host or host.strip("[]") in self._origin_hosts

    async def _admit(self, conn: Any) -> None:
        """Right after the handshake: a tab with a valid capability from the viewer's own page,
        within the bounds, is admitted; any other is closed before anything is sent."""
        handshake = _handshake(self._server, conn.client_id)
        path, origin = handshake if handshake is not None else (None, None)
        try:
            grant = self.access.admit(conn.client_id, path, origin, self._origin_ok)
        except Refused as exc:
            logger.warning("viewer connection refused: %s", exc)
            connection = self._server._websock_server._live_connections.get(conn.client_id)
            if connection is not None:
                await connection.close(1008, str(exc)[:120])
            return
        with self._lock:
            self._grants[conn.client_id] = grant

    async def _release(self, conn: Any) -> None:
        self.access.release(conn.client_id)
        with self._lock:
            self._grants.pop(conn.client_id, None)

    def _on_connect(self, client: Any) -> None:
        with self._lock:
            grant = self._grants.get(client.client_id)
        if grant is None:
            return  # refused at the handshake: closed, nothing to show
        kind, result_id = grant.kind, grant.id
        try:
            if kind == "front":  # a front's tab shows one point: part of what is prepared
                prepared = self.prepare(kind, result_id, grant.methods)
            else:
                prepared = self.prepare(kind, result_id)
        except LookupError as exc:  # unknown, unfinished or deleted
            reason = markdown_text(without_paths(exc))
            shown = f"{markdown_text(kind)} {int(result_id)}"
            client.gui.add_markdown(f"**Cannot show {shown}:** {reason}")
            return
        except Exception:
            logger.exception("viewer cannot prepare %s %d", kind, result_id)
            client.gui.add_markdown(
                f"**Cannot show {markdown_text(kind)} {int(result_id)}** (see the server log)."
            )
            return
        session = self._build_session(client, kind, result_id, prepared)
        _choose_methods(session, grant.methods)
        with self._lock:
            self._sessions[client.client_id] = session
        self.player.add(client.client_id, session.tick)

    def _on_disconnect(self, client: Any) -> None:
        self.player.remove(client.client_id)
        with self._lock:
            self._sessions.pop(client.client_id, None)

    def _build_session(
        self, client: Any, kind: str, result_id: int, prepared: PreparedComparison
    ) -> ViewerSession:
        c = prepared.comparison
        with client.atomic():
            scene = ComparisonScene(client, prepared)
            client.camera.up_direction = (0.0, 0.0, 1.0)
            frame_client(client, scene)
            width = canvas_width(client)
            compact = width is not None and width < NARROW_PX
            gui = _add_gui(client.gui, scene, autoplay=self.autoplay, compact=compact)
        clock = PlaybackClock(c.duration)
        session = ViewerSession(
            client=client, kind=kind, id=result_id, scene=scene, clock=clock, gui=gui
        )
        _wire(session, gui)
        _fit_to_screen(session)
        if self.autoplay:
            clock.play()
        else:
            gui["play"].icon = "player-play"
        return session


# The viewer's own layout (not connection handling) -------------------------------------------

#: Canvas width [px] below which viser shows its phone layout (Mantine's ``xs`` = 36 em): the
#: panel is a bottom sheet the server cannot collapse, so the GUI is built compact there.
NARROW_PX = 576
#: Canvas width [px] below which the floating control panel starts minimised (a bar the user
#: can open): at 640 px its medium width would cover half the scene.
MINIMISE_PX = 900


#: Width of viser's floating control panel ("medium") with its margin [px].
PANEL_PX = 340


def frame_client(client: Any, scene: ComparisonScene) -> None:
    """Point a tab's camera at everything in the scene, for its canvas' shape when known, in the
    part of a wide canvas that the open control panel leaves free."""
    aspect, covered = 1.6, 0.0
    width = canvas_width(client)
    with contextlib.suppress(AssertionError, AttributeError):
        aspect = float(client.camera.aspect)  # known once the browser has reported its camera
    if width is not None and width >= MINIMISE_PX:
        covered = PANEL_PX / width
    position, look_at = scene.camera(aspect=aspect, covered_right=covered)
    client.camera.fov = FOV
    client.camera.position = position
    client.camera.look_at = look_at


def canvas_width(client: Any) -> int | None:
    """The tab's canvas width [px], None before its first camera message (viser connects a tab
    only after that message, so it is normally known)."""
    try:
        return int(client.camera.image_width)
    except AssertionError:
        return None


def _fit_to_screen(session: ViewerSession) -> None:
    """Once the browser has reported its canvas (viser connects a tab after its first camera
    message, so usually already): frame the scene for the canvas' real shape, and on a narrow
    screen minimise the control panel so that it does not cover the canvas."""
    client = session.client
    fitted = threading.Event()

    def fit(_: Any = None) -> None:
        if fitted.is_set():
            return
        width = canvas_width(client)
        if width is None:  # no camera message yet: wait for one
            return
        fitted.set()
        with session.lock, client.atomic():
            frame_client(client, session.scene)
        if width < MINIMISE_PX:
            client.gui.main_panel.minimize()
            session.panel_minimised = True

    client.camera.on_update(fit)
    fit()


def _plot_series(labels: tuple[str, str]) -> tuple[dict[str, Any], ...]:
    """uPlot series of the power panel: time, the solid and ghost robots' power, the cursor."""
    solid, ghost = labels
    return (
        {"label": "t [s]"},
        {"label": f"{trajectory_label(solid)} [W]", "stroke": trajectory_colour(solid), "width": 2},
        {"label": f"{trajectory_label(ghost)} [W]", "stroke": trajectory_colour(ghost), "width": 2},
        {"label": "now", "stroke": "#444", "width": 1, "scale": "cursor"},
    )


def _add_gui(
    gui: Any, scene: ComparisonScene, *, autoplay: bool, compact: bool = False
) -> dict[str, Any]:
    """A tab's controls: play, time, speed, layout, which method each robot shows, the phase of
    the moment, the power curve; and whose the human is (or why there is none).

    ``compact`` (a narrow screen): viser's phone layout shows the panel as a bottom sheet that
    the server cannot collapse, so everything but play and time goes into a closed folder.
    """
    c = scene.prepared.comparison
    solid, ghost = scene.shown["standard"], scene.shown["optimized"]
    handles = {
        "play": gui.add_button("Pause" if autoplay else "Play", icon="player-pause"),
        "time": gui.add_slider(
            "Time [s]", min=0.0, max=round(c.duration, 3), step=0.01, initial_value=0.0
        ),
    }
    if compact:
        with gui.add_folder("Details", expand_by_default=False):
            handles.update(_details(gui, scene, solid, ghost))
        return handles
    handles.update(_details(gui, scene, solid, ghost))
    return handles


def _safety_text(scene: ComparisonScene) -> str:
    """The plan's safety check in one paragraph: every method's first contact (marked in red
    on its links from then on), or the smallest clearance, or why it was not checked."""
    prepared = scene.prepared
    safety = prepared.safety
    if not safety:
        return ""
    if safety.get("checked") is not True:
        return "**Safety:** " + markdown_text(str(safety.get("reason") or "not checked"))
    firsts = [(label, contacts[0][2]) for label, contacts in prepared.contacts.items()
              if contacts and label in prepared.comparison.choices]  # fmt: skip
    if not firsts:
        clearance = safety.get("min_clearance")
        shown = "n/a" if clearance is None else f"{1000 * float(clearance):.1f} mm"
        return f"**Safety:** no contact (min clearance {shown})."
    lines = [f"{markdown_text(trajectory_label(label))}: {markdown_text(text)}"
             for label, text in firsts]  # fmt: skip
    return "**Unsafe** (contacts marked in red from their first time on):  \n" + "  \n".join(lines)


def _details(gui: Any, scene: ComparisonScene, solid: str, ghost: str) -> dict[str, Any]:
    c = scene.prepared.comparison
    gui.add_markdown(f"**{markdown_text(c.title)}**")
    missing = scene.prepared.missing_meshes
    if missing:  # those links are drawn without their bodies
        gui.add_markdown(
            f"**{len(missing)} mesh file(s) missing:** "
            + markdown_text(", ".join(missing[:3]) + (", …" if len(missing) > 3 else ""))
            + ". Their links are drawn without bodies: add the robot as a zip with its meshes."
        )
    safety = _safety_text(scene)
    if safety:
        gui.add_markdown(safety)
    handles = {
        "speed": gui.add_dropdown("Speed", tuple(_SPEED_NAMES), initial_value="1x"),
        "layout": gui.add_dropdown("Layout", tuple(_LAYOUT_NAMES), initial_value="side by side"),
    }
    names = {trajectory_label(m): m for m in c.choices}
    handles["solid"] = gui.add_dropdown(
        "Solid robot", tuple(names), initial_value=trajectory_label(solid)
    )
    handles["ghost"] = gui.add_dropdown(
        "Ghost robot", tuple(names), initial_value=trajectory_label(ghost)
    )
    handles["phase"] = gui.add_markdown(_phase_text(scene.phases_now, scene.shown))
    handles["human"] = gui.add_markdown(markdown_text(c.human_note or no_human_text(c)))
    handles["plot"] = gui.add_uplot(
        power_plot(c, 0.0, labels=(solid, ghost)),
        _plot_series((solid, ghost)),
        title="Mechanical power Σ|τ·ω| [W]",
        scales={"x": {"time": False}, "cursor": {"range": (0.0, 1.0)}},
        axes=({}, {"size": 44}),
        aspect=1.6,
        legend={"show": True},
    )
    return handles


def _wire(session: ViewerSession, gui: dict[str, Any]) -> None:
    """Connect a tab's controls to its session."""
    play, speed, time_slider, layout = gui["play"], gui["speed"], gui["time"], gui["layout"]
    names = {trajectory_label(m): m for m in session.comparison.choices}

    def on_time(event: Any) -> None:
        if event.client is None:
            return  # our own update from the playback loop
        with session.lock:
            session.clock.pause()
            play.label, play.icon = "Play", "player-play"
        session.seek(float(time_slider.value))

    def on_method(_: Any) -> None:
        session.set_methods(names[gui["solid"].value], names[gui["ghost"].value])

    play.on_click(lambda _: session.toggle())
    speed.on_update(lambda _: session.set_speed(_SPEED_NAMES[speed.value]))
    time_slider.on_update(on_time)
    layout.on_update(lambda _: session.set_layout(_LAYOUT_NAMES[layout.value]))
    gui["solid"].on_update(on_method)
    gui["ghost"].on_update(on_method)


def _choose_methods(session: ViewerSession, methods: tuple[str, str] | None) -> None:
    """Show the Compare page's chosen pair (ignored unless both were planned and differ)."""
    choices = session.comparison.choices
    if methods is None or methods[0] == methods[1] or not set(methods) <= set(choices):
        return
    session.gui["solid"].value = trajectory_label(methods[0])
    session.gui["ghost"].value = trajectory_label(methods[1])
    session.set_methods(*methods)


def _url_host(host: str) -> str:
    if host in ("0.0.0.0", "::", ""):
        return "127.0.0.1"
    return f"[{host}]" if ":" in host else host
