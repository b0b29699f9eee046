"""Analysis of human lifts: EMG, pose, sync, repetitions, phases, energetics, the HumanTemplate.

A plain library (numpy/scipy; the human arm model from ``app.planning``). ``analyze_files`` and
``analyze_recordings`` are the entry points of the CLI and the service; the functions below them
work on plain arrays.
"""

from app.analysis.cohort import (
    CohortError,
    CohortOptions,
    CohortResult,
    RecordingMeasures,
    cohort_statistics,
    compare_groups,
    recording_measures,
    write_cohort_csv,
)
from app.analysis.cohort_plots import write_cohort_plots
from app.analysis.downsample import minmax_downsample
from app.analysis.emg import (
    activation_order,
    detect_onsets,
    emg_envelope,
    emg_filter,
    emg_process,
    moving_rms,
    normalize_amplitude,
    peak_times,
    saturation_flags,
    tkeo,
)
from app.analysis.energetics import (
    Energetics,
    PhaseEnergetics,
    human_arm_dynamics,
    lift_energetics,
)
from app.analysis.overlays import AnalysisOverlays, OverlaysError
from app.analysis.pipeline import (
    AnalysisResult,
    LiftReport,
    MuscleSeries,
    PhaseStats,
    RecordingAnalysis,
    analyze_files,
    analyze_recordings,
    merge_recordings,
)
from app.analysis.plots import write_analysis_plots
from app.analysis.pose import ArmAngles, angles_from_channels, arm_angles, joint_angles
from app.analysis.replay import (
    HumanReplay,
    ReplayError,
    lift_time_map,
    lifts_with_angles,
    replay_from_overlays,
    replay_lift,
    two_link_points,
)
from app.analysis.segmentation import Lift, Phase, detect_emg_lifts, detect_lifts, split_phases
from app.analysis.sync import estimate_offset, event_offset, resample
from app.analysis.template import LiftProfile, build_template, lift_profile

__all__ = [
    "AnalysisOverlays",
    "AnalysisResult",
    "ArmAngles",
    "CohortError",
    "CohortOptions",
    "CohortResult",
    "Energetics",
    "HumanReplay",
    "Lift",
    "LiftProfile",
    "LiftReport",
    "MuscleSeries",
    "OverlaysError",
    "Phase",
    "PhaseEnergetics",
    "PhaseStats",
    "RecordingAnalysis",
    "RecordingMeasures",
    "ReplayError",
    "activation_order",
    "analyze_files",
    "analyze_recordings",
    "angles_from_channels",
    "arm_angles",
    "build_template",
    "cohort_statistics",
    "compare_groups",
    "detect_emg_lifts",
    "detect_lifts",
    "detect_onsets",
    "emg_envelope",
    "emg_filter",
    "emg_process",
    "estimate_offset",
    "event_offset",
    "human_arm_dynamics",
    "joint_angles",
    "lift_energetics",
    "lift_profile",
    "lift_time_map",
    "lifts_with_angles",
    "merge_recordings",
    "minmax_downsample",
    "moving_rms",
    "normalize_amplitude",
    "peak_times",
    "recording_measures",
    "replay_from_overlays",
    "replay_lift",
    "resample",
    "saturation_flags",
    "split_phases",
    "tkeo",
    "two_link_points",
    "write_analysis_plots",
    "write_cohort_csv",
    "write_cohort_plots",
]
