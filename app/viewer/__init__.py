"""The 3-D viewer (viser): comparison scenes, playback, kinematics and offline exports.

Viser only: no web framework, no database. ``ViewerServer`` serves one scene per browser tab
from a ``(kind, id) -> PreparedComparison`` callable that the service layer supplies
(``app.services``), and ``scene_html``/``report_html`` write self-contained exports.
"""

from app.viewer.comparison import (
    Comparison,
    ComparisonError,
    comparison_from_arrays,
)
from app.viewer.export import report_html, scene_html
from app.viewer.kinematics import KinematicsError, UrdfChain
from app.viewer.playback import PlaybackClock, Player
from app.viewer.scene import ComparisonScene, PreparedCache, PreparedComparison
from app.viewer.server import ViewerServer

__all__ = [
    "Comparison",
    "ComparisonError",
    "ComparisonScene",
    "KinematicsError",
    "PlaybackClock",
    "Player",
    "PreparedCache",
    "PreparedComparison",
    "UrdfChain",
    "ViewerServer",
    "comparison_from_arrays",
    "report_html",
    "scene_html",
]
