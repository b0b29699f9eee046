"""The dashboard: the 3-D viewer (viser), comparison scenes, playback, exports, the static pages.

Service layer: may import FastAPI and viser. ``attach_dashboard(app, settings)`` is the one call
the app needs; ``seed_demo(settings)`` fills an empty database for ``bioplan serve --demo``.
"""

from app.viewer.comparison import (
    Comparison,
    ComparisonError,
    comparison_from_arrays,
    load_comparison,
)
from app.viewer.dashboard import DashboardState, attach_dashboard, viewer_hook
from app.viewer.demo_seed import seed_demo, synthetic_curls, synthetic_curls_csv
from app.viewer.export import report_html, scene_html
from app.viewer.kinematics import KinematicsError, UrdfChain
from app.viewer.playback import PlaybackClock, Player
from app.viewer.scene import ComparisonScene, PreparedCache, PreparedComparison
from app.viewer.server import ViewerServer
from app.viewer.signals import AnalysisPending, SignalsCache

__all__ = [
    "AnalysisPending",
    "Comparison",
    "ComparisonError",
    "ComparisonScene",
    "DashboardState",
    "KinematicsError",
    "PlaybackClock",
    "Player",
    "PreparedCache",
    "PreparedComparison",
    "SignalsCache",
    "UrdfChain",
    "ViewerServer",
    "attach_dashboard",
    "comparison_from_arrays",
    "load_comparison",
    "report_html",
    "scene_html",
    "seed_demo",
    "synthetic_curls",
    "synthetic_curls_csv",
    "viewer_hook",
]
