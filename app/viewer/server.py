"""The 3-D viewer: one viser server, one comparison scene per browser tab.

The Compare page embeds ``http://HOST:PORT/?websocket=ws://HOST:PORT/bioplan/<kind>/<id>`` in
an iframe. When a tab connects, this module finds out which comparison it wants and builds that
tab's own scene (``client.scene``), GUI (play, pause, speed, scrub, layout, the phase of the
moment, the power curve in uPlot) and playback clock. So two tabs can show two comparisons at
once. One ``Player`` thread advances every playing tab.

Which comparison a tab wants: viser 1.1 has no public API for a client's URL (``ClientHandle``
offers its id, camera, GUI, scene and localStorage, none of which the embedding page can set).
So there are two ways in, tried in order:

1. The fast path reads the websocket handshake's request path from viser's private connection
   table (``_handshake_path``). It tells tabs apart exactly. ``tests/viewer/test_server.py``
   connects a real websocket and fails, naming this function, if a viser upgrade breaks it.
2. The fallback uses only our own API: ``client_url(kind, id)`` is what the Compare page asks
   for just before it loads the iframe, so each call records that request, and a client whose
   path cannot be read takes the oldest request of the last ``PENDING_SECONDS``. A tab that
   connects on the fast path takes its own request off that queue. Two tabs opened within the
   same second could swap on the fallback; the log warns once that the fallback is in use.

viser takes the next free port when the one asked for is busy: ``start()`` returns the real
port and ``url`` reports it. Its websocket checks neither origin nor credentials, so it binds to
loopback unless told otherwise.
"""

from __future__ import annotations

import contextlib
import logging
import re
import sys
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

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

Prepare = Callable[[str, int], PreparedComparison]

#: The websocket path that names a tab's comparison.
_PATH = re.compile(r"^/bioplan/(plan|simulation)/([1-9][0-9]{0,9})/?$")
_METHOD = re.compile(r"^[a-z_]{1,32}$")
#: Seconds between updates of the time slider and the plot's cursor while playing. Each update
#: re-renders viser's control panel; at 10 Hz that cost a software-rendered canvas about a third
#: of its frames, at 4 Hz about a seventh.
GUI_PERIOD = 0.25
#: Seconds a Compare page's request waits for a tab whose websocket path cannot be read.
PENDING_SECONDS = 120.0
_LAYOUT_NAMES: dict[str, Layout] = {"side by side": "side_by_side", "ghost overlay": "ghost"}
_SPEED_NAMES = {f"{s:g}x": s for s in SPEEDS}


def parse_client_path(path: str | None) -> tuple[str, int] | None:
    """``(kind, id)`` from a websocket path ``/bioplan/<plan|simulation>/<id>``, else None."""
    if not path:
        return None
    match = _PATH.match(path.split("?", 1)[0])
    if match is None:
        return None
    return match.group(1), int(match.group(2))


def parse_client_methods(path: str | None) -> tuple[str, str] | None:
    """The two methods ``(solid, ghost)`` a websocket path asks for (``?methods=a,b``, as the
    Compare page's choice), else None."""
    if not path or "?" not in path:
        return None
    for part in path.split("?", 1)[1].split("&"):
        key, _, value = part.partition("=")
        pair = value.split(",")
        if key == "methods" and len(pair) == 2 and all(_METHOD.match(m) for m in pair):
            return pair[0], pair[1]
    return None


def _handshake_path(server: Any, client_id: int) -> str | None:
    """The request path of a client's websocket handshake, or None when it cannot be read.

    Private viser internals (viser 1.1 keeps each live ``websockets`` connection by client id);
    see the module docstring for the fallback.
    """
    try:
        connection = server._websock_server._live_connections[client_id]
        return str(connection.request.path)
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
        """Pose the robots for the clock's time; refresh the GUI at most every GUI_PERIOD."""
        with self.lock:
            t = self.clock.time()
            index = self.comparison.index_at(t)
            moved = index != self.scene.index
            if moved or self.dirty:
                with self.client.atomic():
                    phases = self.scene.show(index)
                self.stats.frame()
            now = time.monotonic()
            if self.dirty or (moved and now - self.last_gui >= GUI_PERIOD):
                self._refresh_gui(t, phases if moved or self.dirty else None)
                self.last_gui = now
                self.dirty = False

    def _refresh_gui(self, t: float, phases: dict[str, str] | None) -> None:
        c = self.comparison
        if phases is None:
            phases = {
                slot: c.phase_at(label, self.scene.index)
                for slot, label in self.scene.shown.items()
            }
            if self.scene.human is not None:
                phases["human"] = self.scene.human.phase
        slider = self.gui["time"]
        slider.value = round(min(t, float(slider.max)), 3)
        text = _phase_text(phases, self.scene.shown)
        if text != self.phase_text:  # only at a phase boundary
            self.phase_text = text
            self.gui["phase"].content = text
        self.gui["plot"].data = power_plot(c, t, labels=self._plotted())

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
    """

    def __init__(
        self,
        prepare: Prepare,
        *,
        host: str = "127.0.0.1",
        port: int = 8080,
        fps: float = 60.0,
        autoplay: bool = True,
    ) -> None:
        self.prepare = prepare
        self.host = host
        self.requested_port = port
        self.autoplay = autoplay
        self.player = Player(fps)
        self._server: Any = None
        self._sessions: dict[int, ViewerSession] = {}
        self._lock = threading.Lock()
        #: (monotonic time, kind, id) the Compare page asked for, oldest first.
        self._pending: deque[tuple[float, str, int]] = deque(maxlen=64)
        self._warned_fallback = False

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
        (solid, ghost) on the two robots (None: the comparison's default pair).

        Also records the request for a tab whose websocket path cannot be read (the fallback).
        """
        with self._lock:
            self._pending.append((time.monotonic(), kind, int(result_id)))
        host = _url_host(self.host)
        # The websocket address is itself a query value of the page's address: its own query
        # (the methods) is percent-encoded so that the viewer page passes it on whole.
        query = "" if methods is None else f"%3Fmethods%3D{methods[0]}%2C{methods[1]}"
        return (
            f"http://{host}:{self.port}/?websocket=ws://{host}:{self.port}/bioplan/"
            f"{kind}/{int(result_id)}{query}&hideViserLogo"
        )

    def sessions(self) -> list[dict[str, Any]]:
        with self._lock:
            sessions = list(self._sessions.values())
        return [s.describe() for s in sessions]

    # clients -----------------------------------------------------------------------------

    def _target(self, client_id: int) -> tuple[str, int] | None:
        """The comparison a new client wants: its handshake path, else the oldest request."""
        return self._target_of(_handshake_path(self._server, client_id))

    def _target_of(self, path: str | None) -> tuple[str, int] | None:
        now = time.monotonic()
        with self._lock:
            while self._pending and now - self._pending[0][0] > PENDING_SECONDS:
                self._pending.popleft()
            if path is not None:
                target = parse_client_path(path)
                for entry in self._pending:
                    if entry[1:] == target:
                        self._pending.remove(entry)  # this tab's request is served
                        break
                return target
            if not self._warned_fallback:
                self._warned_fallback = True
                logger.warning(
                    "cannot read viewer clients' websocket paths (viser's internals changed?); "
                    "matching tabs to the Compare page's requests in order instead"
                )
            return self._pending.popleft()[1:] if self._pending else None

    def _on_connect(self, client: Any) -> None:
        path = _handshake_path(self._server, client.client_id)
        target = self._target_of(path)
        if target is None:
            client.gui.add_markdown(
                "**No comparison selected.** Open one from the dashboard's Compare page."
            )
            return
        kind, result_id = target
        try:
            prepared = self.prepare(kind, result_id)
        except LookupError as exc:  # unknown, unfinished or deleted
            client.gui.add_markdown(f"**Cannot show {kind} {result_id}:** {exc}")
            return
        except Exception:
            logger.exception("viewer cannot prepare %s %d", kind, result_id)
            client.gui.add_markdown(f"**Cannot show {kind} {result_id}** (see the server log).")
            return
        session = self._build_session(client, kind, result_id, prepared)
        _choose_methods(session, parse_client_methods(path))
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


def _details(gui: Any, scene: ComparisonScene, solid: str, ghost: str) -> dict[str, Any]:
    c = scene.prepared.comparison
    gui.add_markdown(f"**{c.title}**")
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
    handles["human"] = gui.add_markdown(c.human_note or no_human_text(c))
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
