"""Recording readers: one per format, format sniffing, Recording/Channel types.

Every reader returns a :class:`Recording` in SI units (EMG in V, angles in rad, markers in m;
MediaPipe landmarks in normalised image units) and raises only :class:`RecordingError`, whose
message names the file, the line or channel, and what was expected.
"""

from app.recordings._mediapipe import LANDMARK_NAMES
from app.recordings._read import read_bytes, read_recording
from app.recordings._sniff import FORMATS, sniff_format
from app.recordings.muscles import map_muscle
from app.recordings.types import (
    SITES,
    Channel,
    ChannelKind,
    DatalogSensor,
    Recording,
    RecordingError,
    Site,
)

__all__ = [
    "FORMATS",
    "LANDMARK_NAMES",
    "SITES",
    "Channel",
    "ChannelKind",
    "DatalogSensor",
    "Recording",
    "RecordingError",
    "Site",
    "map_muscle",
    "read_bytes",
    "read_recording",
    "sniff_format",
]
