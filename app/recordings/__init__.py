"""Recording readers: one per format, format sniffing, Recording/Channel types.

Every reader returns a :class:`Recording` in SI units (EMG in V, angles in rad, markers in m;
MediaPipe landmarks in normalised image units) and raises only :class:`RecordingError`, whose
message names the file, the line or channel, and what was expected.
"""

from app.names import MAX_VIDEO_SECONDS
from app.recordings._bids import (
    CONDITION_RULE,
    BidsDataset,
    bids_entities,
    condition_from_files,
    read_bids,
)
from app.recordings._mediapipe import LANDMARK_NAMES
from app.recordings._pose_quality import FrameQuality, arm_quality, image_landmarks
from app.recordings._read import ReadKeywords, read_bytes, read_recording
from app.recordings._sniff import FORMATS, sniff_format
from app.recordings._video_probe import VideoProbe, looks_like_video, probe_video
from app.recordings.muscles import map_muscle
from app.recordings.robot_logs import LOG_FORMATS, RobotLog, read_robot_log, sniff_robot_log
from app.recordings.types import (
    SITES,
    Channel,
    ChannelKind,
    DatalogSensor,
    RateCheck,
    Recording,
    RecordingError,
    Site,
    rate_check,
)
from app.recordings.video import (
    POSE_PYTHON_ENV,
    VIDEO_EXTENSIONS,
    PoseCancelled,
    PoseExtraction,
    SkeletonFrame,
    create_pose_env,
    default_pose_env,
    extract_pose,
    find_pose_python,
    is_video,
    save_skeletons,
)

__all__ = [
    "CONDITION_RULE",
    "FORMATS",
    "LANDMARK_NAMES",
    "LOG_FORMATS",
    "MAX_VIDEO_SECONDS",
    "POSE_PYTHON_ENV",
    "SITES",
    "VIDEO_EXTENSIONS",
    "BidsDataset",
    "Channel",
    "ChannelKind",
    "DatalogSensor",
    "FrameQuality",
    "PoseCancelled",
    "PoseExtraction",
    "RateCheck",
    "ReadKeywords",
    "Recording",
    "RecordingError",
    "RobotLog",
    "Site",
    "SkeletonFrame",
    "VideoProbe",
    "arm_quality",
    "bids_entities",
    "condition_from_files",
    "create_pose_env",
    "default_pose_env",
    "extract_pose",
    "find_pose_python",
    "image_landmarks",
    "is_video",
    "looks_like_video",
    "map_muscle",
    "probe_video",
    "rate_check",
    "read_bids",
    "read_bytes",
    "read_recording",
    "read_robot_log",
    "save_skeletons",
    "sniff_format",
    "sniff_robot_log",
]
