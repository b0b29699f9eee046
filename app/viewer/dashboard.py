"""Attach the dashboard to the service's FastAPI app: static pages, viewer routes, the viewer.

``attach_dashboard(app, settings)`` mounts ``frontend/`` at ``/``, adds the routes of
``app.viewer.routes`` under ``/api/viewer/...`` and arranges for the viser viewer to start once
the app's services run and to stop before they do. The viewer's real address goes into
``services.viewer``, which ``GET /api/viewer`` reports.

The viewer is started through a ``StartupHook`` (``app.main``'s hook type: services in, a stop
function out). ``attach_dashboard`` wraps the app's lifespan to call it, so it works on an app
``create_app`` has already built; ``viewer_hook`` is the same hook for ``create_app(hooks=...)``
(then pass ``start_viewer=False`` here).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fastapi import FastAPI
from starlette.concurrency import run_in_threadpool
from starlette.staticfiles import StaticFiles

from app.viewer.routes import router
from app.viewer.scene import PreparedCache
from app.viewer.server import ViewerServer
from app.viewer.signals import SignalsCache

if TYPE_CHECKING:
    from app.api.deps import Services
    from app.config import Settings

logger = logging.getLogger(__name__)

#: The static pages (repository root, beside ``app/``).
FRONTEND_DIR = Path(__file__).resolve().parents[2] / "frontend"
#: The viewer's port when the settings give none (viser's usual port).
DEFAULT_VIEWER_PORT = 8080


@dataclass
class DashboardState:
    """What the dashboard routes use (``app.state.dashboard``)."""

    settings: Settings
    signals: SignalsCache = field(default_factory=SignalsCache)
    prepared: PreparedCache | None = None
    viewer: ViewerServer | None = None
    _services: Services | None = None

    def services(self) -> Services:
        if self._services is None:
            raise RuntimeError("the dashboard's services are not running")
        return self._services


def _warm_imports() -> None:
    # yourdfpy pulls in trimesh (about a second): import it before the first tab needs it.
    try:
        import yourdfpy  # type: ignore[import-untyped]  # noqa: F401
    except ImportError:  # pragma: no cover - a dependency of the package
        logger.warning("yourdfpy is not installed: the 3-D viewer cannot load robots")


def viewer_hook(
    settings: Settings,
    *,
    state: DashboardState | None = None,
    start_viewer: bool = True,
    fps: float = 60.0,
) -> Callable[[Services], Callable[[], None] | None]:
    """A ``StartupHook`` that starts the viewer on the running services.

    Args:
        settings: ``viewer_host`` and ``viewer_port`` (``DEFAULT_VIEWER_PORT`` when unset).
        state: the dashboard state to fill in (a fresh one otherwise).
        start_viewer: False serves exports and curves without a 3-D viewer.
        fps: playback updates per second.
    """
    from app.viewer.comparison import load_comparison

    dashboard = state or DashboardState(settings=settings)

    def hook(services: Services) -> Callable[[], None] | None:
        dashboard._services = services
        dashboard.prepared = PreparedCache(
            lambda kind, result_id: load_comparison(services, kind, result_id)
        )
        threading.Thread(target=_warm_imports, name="bioplan-viewer-warmup", daemon=True).start()
        if not start_viewer:
            return None
        viewer = ViewerServer(
            dashboard.prepared,
            host=settings.viewer_host,
            port=settings.viewer_port or DEFAULT_VIEWER_PORT,
            fps=fps,
        )
        port = viewer.start()
        dashboard.viewer = viewer
        # What GET /api/viewer reports: the port viser really took.
        services.viewer.clear()
        services.viewer.update(
            {"host": settings.viewer_host, "port": port, "url": viewer.url, "running": True}
        )
        logger.info("3-D viewer at %s", viewer.url)

        def stop() -> None:
            viewer.stop()
            dashboard.viewer = None
            services.viewer.clear()

        return stop

    return hook


def attach_dashboard(
    app: FastAPI,
    settings: Settings,
    *,
    start_viewer: bool = True,
    frontend_dir: Path | None = None,
    fps: float = 60.0,
) -> None:
    """Serve the dashboard from ``app``.

    Mounts the static pages at ``/`` (after every API route), adds ``/api/viewer/...`` routes,
    and starts the viser viewer in the app's lifespan (after the services, stopped before
    them).

    Args:
        app: the app from ``app.main.create_app``.
        settings: the same settings.
        start_viewer: start the 3-D viewer (False: pages, curves and exports only).
        frontend_dir: the static pages (default: ``frontend/`` of the repository).
        fps: viewer playback updates per second.

    Raises:
        FileNotFoundError: the frontend folder has no ``index.html``.
    """
    folder = Path(frontend_dir or FRONTEND_DIR)
    if not (folder / "index.html").is_file():
        raise FileNotFoundError(f"the dashboard's pages are missing: no index.html in {folder}")
    state = DashboardState(settings=settings)
    app.state.dashboard = state
    app.include_router(router)
    app.mount("/", StaticFiles(directory=folder, html=True), name="dashboard")
    hook = viewer_hook(settings, state=state, start_viewer=start_viewer, fps=fps)
    original = app.router.lifespan_context

    @asynccontextmanager
    async def lifespan(app_: Any) -> AsyncIterator[Any]:
        async with original(app_) as inner:
            stop = await run_in_threadpool(hook, app_.state.services)
            try:
                yield inner
            finally:
                if stop is not None:
                    await run_in_threadpool(stop)

    app.router.lifespan_context = lifespan
