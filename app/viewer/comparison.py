"""A finished comparison (plan or simulation), as the viewer and the Compare page use it.

``Comparison`` holds both trajectories on one time grid in SI units, the phase of every sample,
the robot's URDF text and payload; ``comparison_from_arrays`` builds one from a job's stored
arrays and result (``app.services.comparisons`` reads those from the database). The planner's
arrays differ a little between plans and simulations (a simulation has measured ``q``/``qd``
and commanded ``qdd_cmd``); this is the one place that knows.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from app.names import METHODS, PHASE_BOUNDS_DEG
from app.names import PHASES as _PHASES

if TYPE_CHECKING:
    from app.analysis.replay import HumanReplay
    from app.planning.planner import PlanTask
    from app.planning.robots import Robot

FloatArray = NDArray[np.float64]
#: A stored result's arrays by name (``t``, ``<method>_q``...), as decoded [SI units].
StoredArrays = Mapping[str, ArrayLike]
Kind = Literal["plan", "simulation", "front"]
#: ``front``: one point of a Pareto front beside the quintic at its duration (two "methods":
#: ``quintic`` and the point's id, ``p0``...).
KINDS: tuple[Kind, ...] = ("plan", "simulation", "front")
LABELS: tuple[str, str] = ("standard", "optimized")
#: Phase names and what they mean in a curl (``app.names.PHASES``).
PHASES = {p.name: p.label for p in _PHASES}


class ComparisonError(LookupError):
    """Stored arrays that do not make a comparison (a key missing, a shape wrong)."""


class NothingToCompare(ComparisonError):
    """A result with fewer than two planned trajectories: no pair of ``methods`` to show."""


@dataclass(frozen=True)
class Comparison:
    """Standard and optimised trajectories of one plan or simulation.

    Attributes:
        kind: ``"plan"`` or ``"simulation"``.
        id: the plan's or simulation's id (= its job id).
        robot: robot name.
        joint_names: (n,) joints, the column order of the arrays.
        t: (T,) time grid [s].
        q, qd, qdd, tau: label -> (T, n) angles [rad], velocities [rad/s], accelerations
            [rad/s^2], torques [Nm]; labels ``standard`` and ``optimized``.
        power: label -> (T,) mechanical power sum_j |tau_j qd_j| [W].
        energy: label -> (T,) its running integral [J].
        elbow_flexion_deg: label -> (T,) human-equivalent elbow flexion [deg].
        phase_bounds_deg: (A/B, B/C) bounds [deg].
        phase_times: label -> (t_AB, t_BC) [s], NaN when a bound is never reached.
        elbow_joint: column of the elbow.
        urdf: the robot's URDF text (no meshes: primitives only).
        payload_body: URDF link that carries the payload.
        payload_mass: [kg].
        payload_com: (3,) payload centre in the payload body's frame [m].
        payload_size: (3,) payload box extents [m] (zeros: a point mass).
        result: the job's JSON result (the CLI's ``--json``).
        shown: the planned methods shown as ``standard`` and ``optimized`` (in that order), as
            chosen by the Compare page's ``methods=a,b``.
        urdf_path: the robot's URDF file, so its meshes are found (None: ``urdf`` text only).
        package_dirs: folders ``package://`` mesh paths resolve in.
        allowed_roots: meshes outside these folders are not read (an uploaded robot's folder);
            None: no confinement (built-in robots).
        locks: locked joints -> values [rad or m] (drawn at their values).
        methods: the planning methods whose trajectories the arrays hold (``app.names.METHODS``
            order); the dicts above hold them under their names too. Empty for results stored
            before methods existed (only ``standard`` and ``optimized``).
        obstacles: the sidecar's obstacles the plan was checked against (base frame, SI:
            ``name``, ``kind`` box/cylinder/plane, ``position``, ``rpy`` [rad], ``size``,
            ``radius``, ``length``, ``normal``); drawn translucent.
        human: the recorded lift replayed on this comparison's time grid, or None.
        human_note: why there is no human (or what was assumed for it); shown in the viewer.
        template: where the human template came from and what its angle is
            (:func:`template_provenance`); the Compare page, the viewer and the report say it.
    """

    kind: Kind
    id: int
    robot: str
    joint_names: tuple[str, ...]
    t: FloatArray
    q: dict[str, FloatArray]
    qd: dict[str, FloatArray]
    qdd: dict[str, FloatArray]
    tau: dict[str, FloatArray]
    power: dict[str, FloatArray]
    energy: dict[str, FloatArray]
    elbow_flexion_deg: dict[str, FloatArray]
    phase_bounds_deg: tuple[float, float]
    phase_times: dict[str, tuple[float, float]]
    elbow_joint: int
    urdf: str
    payload_body: str
    payload_mass: float
    payload_com: FloatArray
    payload_size: FloatArray
    result: dict[str, Any] = field(default_factory=dict)
    shown: tuple[str, str] = ("quintic", "paper")
    urdf_path: Path | None = None
    package_dirs: tuple[Path, ...] = ()
    allowed_roots: tuple[Path, ...] | None = None
    locks: dict[str, float] = field(default_factory=dict)
    methods: tuple[str, ...] = ()
    human: HumanReplay | None = None
    human_note: str = ""
    template: dict[str, Any] = field(default_factory=dict)
    obstacles: tuple[dict[str, Any], ...] = ()

    @property
    def choices(self) -> tuple[str, ...]:
        """The trajectories a viewer can show: every method, else ``standard``/``optimized``."""
        return self.methods if len(self.methods) >= 2 else LABELS

    @property
    def default_pair(self) -> tuple[str, str]:
        """(solid, ghost) shown first: the pair the page chose (``shown``) when both were
        planned, else the standard quintic and the paper's (or the optimised) one."""
        if len(self.methods) < 2:
            return LABELS
        if all(m in self.methods for m in self.shown):
            return self.shown
        solid = "quintic" if "quintic" in self.methods else self.methods[0]
        ghost = "paper" if "paper" in self.methods else next(m for m in self.methods if m != solid)
        return solid, ghost

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    @property
    def title(self) -> str:
        c = self.result.get("conditions", {})
        objective = c.get("objective", "?")
        return (
            f"{self.kind.capitalize()} #{self.id}: {self.robot}, {self.payload_mass:g} kg, "
            f"{self.duration:g} s, objective {objective}"
        )

    def phase_at(self, label: str, index: int) -> str:
        """``"A"``, ``"B"`` or ``"C"``: the phase of sample ``index`` of one trajectory."""
        return phase_of(float(self.elbow_flexion_deg[label][index]), self.phase_bounds_deg)

    def index_at(self, time: float) -> int:
        """The sample nearest to ``time`` [s] (clamped to the grid)."""
        i = int(np.searchsorted(self.t, time))
        if i <= 0:
            return 0
        if i >= len(self.t):
            return len(self.t) - 1
        return i if self.t[i] - time < time - self.t[i - 1] else i - 1

    def curves(self, *, points: int = 400) -> dict[str, Any]:
        """JSON-ready curves for the Compare page, decimated to at most ``points`` samples.

        Returns:
            ``{"t": [...], "joint_names", "standard"/"optimized": {"q", "qd", "qdd", "tau":
            (T, n) lists, "power", "energy", "elbow_flexion_deg", "elbow_velocity_normalised":
            (T,) lists}, "human": None or {"elbow_velocity_normalised", "elbow_flexion_deg",
            "shoulder_deg": (T,) lists}}`` (the human's lift on the same grid).
        """
        if points < 2:
            raise ValueError(f"points must be >= 2, got {points}")
        n = len(self.t)
        idx = np.unique(np.linspace(0, n - 1, min(points, n)).round().astype(int))
        out: dict[str, Any] = {"t": _clean(self.t[idx]), "joint_names": list(self.joint_names)}
        for label in LABELS:
            out[label] = {
                "q": _clean(self.q[label][idx]),
                "qd": _clean(self.qd[label][idx]),
                "qdd": _clean(self.qdd[label][idx]),
                "tau": _clean(self.tau[label][idx]),
                "power": _clean(self.power[label][idx]),
                "energy": _clean(self.energy[label][idx]),
                "elbow_flexion_deg": _clean(self.elbow_flexion_deg[label][idx]),
                "elbow_velocity_normalised": _clean(self.elbow_velocity_normalised(label)[idx]),
            }
        out["human"] = None if self.human is None else self._human_curves(idx)
        return out

    def elbow_velocity_normalised(self, label: str) -> FloatArray:
        """(T,) the elbow's velocity over its peak |value| (0 when it never moves)."""
        return _over_peak(self.qd[label][:, self.elbow_joint])

    def _human_curves(self, idx: NDArray[np.int_]) -> dict[str, Any]:
        """The replayed lift on the plan's grid: its elbow velocity over its peak (the
        Compare page draws it over the robots'), elbow flexion and shoulder angle [deg]."""
        h = self.human
        assert h is not None
        velocity = np.gradient(h.elbow, h.t) if len(h.t) > 1 else np.zeros_like(h.elbow)
        return {
            "elbow_velocity_normalised": _clean(_over_peak(velocity)[idx]),
            "elbow_flexion_deg": _clean(np.degrees(h.elbow)[idx]),
            "shoulder_deg": _clean(np.degrees(h.shoulder)[idx]),
        }

    def summary(self) -> dict[str, Any]:
        """JSON-ready description without the curves (phases, payload, joints)."""
        return {
            "kind": self.kind,
            "id": self.id,
            "title": self.title,
            "robot": self.robot,
            "joint_names": list(self.joint_names),
            "elbow_joint": self.elbow_joint,
            "duration": self.duration,
            "samples": len(self.t),
            "payload": {
                "mass": self.payload_mass,
                "body": self.payload_body,
                "com": self.payload_com.tolist(),
                "size": self.payload_size.tolist(),
            },
            "phase_bounds_deg": list(self.phase_bounds_deg),
            "phase_times": {
                label: [None if math.isnan(v) else v for v in times]
                for label, times in self.phase_times.items()
            },
            "phases": PHASES,
            "methods": dict(zip(LABELS, self.shown, strict=True)),
            "planned": list(self.methods),
            "floor_tolerance": floor_tolerance(self.kind),
            "template": self.template or template_provenance(self.result),
            "human": {
                "shown": self.human is not None,
                "note": self.human_note,
                "lift": None if self.human is None else dict(self.human.lift),
                "segments_m": None
                if self.human is None
                else {"upper_arm": self.human.upper_arm, "forearm": self.human.forearm},
            },
        }


def _over_peak(values: FloatArray) -> FloatArray:
    peak = float(np.max(np.abs(values), initial=0.0))
    out: FloatArray = values / peak if peak > 0.0 else np.zeros_like(values)
    return out


def trajectory_label(name: str) -> str:
    """What to call a trajectory: a method's label, or "standard quintic" / "optimised"."""
    if name in METHODS:
        return METHODS[name].label
    return {"standard": "standard quintic", "optimized": "optimised"}.get(name, name)


def trajectory_colour(name: str) -> str:
    """A trajectory's CSS colour: its method's (``standard`` = quintic, ``optimized`` = paper)."""
    method = {"standard": "quintic", "optimized": "paper"}.get(name, name)
    return METHODS[method].colour if method in METHODS else "#888888"


def _clean(array: FloatArray) -> list[Any]:
    values: list[Any] = _nan_to_none(np.where(np.isfinite(array), array, np.nan).tolist())
    return values


def _nan_to_none(value: Any) -> Any:
    if isinstance(value, list):
        return [_nan_to_none(v) for v in value]
    if isinstance(value, float) and math.isnan(value):
        return None
    return value


def phase_of(flexion_deg: float, bounds_deg: tuple[float, float]) -> str:
    """The curl phase of an elbow flexion [deg]: A below the first bound, C from the second."""
    if flexion_deg < bounds_deg[0]:
        return "A"
    return "B" if flexion_deg < bounds_deg[1] else "C"


def crossing_times(
    t: FloatArray, flexion_deg: FloatArray, bounds_deg: tuple[float, float]
) -> tuple[float, float]:
    """First times [s] the flexion reaches each bound, linearly interpolated (NaN: never)."""
    out: list[float] = []
    for bound in bounds_deg:
        above = np.flatnonzero(flexion_deg >= bound)
        if above.size == 0:
            out.append(math.nan)
            continue
        i = int(above[0])
        if i == 0:
            out.append(float(t[0]))
            continue
        f0, f1 = float(flexion_deg[i - 1]), float(flexion_deg[i])
        w = (bound - f0) / (f1 - f0)
        out.append(float(t[i - 1] + w * (t[i] - t[i - 1])))
    return out[0], out[1]


def _get(arrays: StoredArrays, key: str) -> FloatArray:
    if key not in arrays:
        raise ComparisonError(f"the stored arrays have no {key!r} (have {sorted(arrays)})")
    return np.asarray(arrays[key], dtype=np.float64)


def _task_and_bounds(
    conditions: Mapping[str, Any], robot: Robot
) -> tuple[PlanTask, tuple[float, float]]:
    """The job's task (start and goal [rad]) and phase bounds [deg], from its conditions."""
    from app.planning.planner import PlanTask

    start = np.radians(np.asarray(conditions.get("start_deg", np.degrees(robot.default_start))))
    goal = np.radians(np.asarray(conditions.get("goal_deg", np.degrees(robot.default_goal))))
    task = PlanTask(np.asarray(start, float), np.asarray(goal, float))
    bounds_raw = conditions.get("phase_bounds_deg") or PHASE_BOUNDS_DEG
    return task, (float(bounds_raw[0]), float(bounds_raw[1]))


def _trajectory(
    arrays: StoredArrays, label: str, kind: str, t: FloatArray, n_joints: int
) -> dict[str, FloatArray]:
    """One trajectory's ``q, qd, qdd, tau`` (T, n) and ``power, energy`` (T,), shapes checked."""
    acc_key = "qdd_cmd" if kind == "simulation" else "qdd"
    out: dict[str, FloatArray] = {}
    for name, key in (("q", "q"), ("qd", "qd"), ("qdd", acc_key), ("tau", "tau")):
        arr = _get(arrays, f"{label}_{key}")
        if arr.shape != (len(t), n_joints):
            raise ComparisonError(
                f"{label}_{key} has shape {arr.shape}: expected ({len(t)}, {n_joints})"
            )
        out[name] = arr
    for name in ("power", "energy"):
        arr = _get(arrays, f"{label}_{name}")
        if arr.shape != t.shape:
            raise ComparisonError(f"{label}_{name} has shape {arr.shape}: expected {t.shape}")
        out[name] = arr
    return out


def _curves(
    arrays: StoredArrays,
    labels: Sequence[str],
    kind: Kind,
    t: FloatArray,
    robot: Robot,
    task: PlanTask,
    bounds: tuple[float, float],
) -> tuple[dict[str, dict[str, FloatArray]], dict[str, tuple[float, float]]]:
    """Per quantity (``q``, ``qd``, ``qdd``, ``tau``, ``power``, ``energy``, ``flex``) the
    arrays of each label, and each label's phase-crossing times (t_AB, t_BC) [s]."""
    from app.planning.planner import elbow_flexion_deg

    data: dict[str, dict[str, FloatArray]] = {
        k: {} for k in ("q", "qd", "qdd", "tau", "power", "energy", "flex")
    }
    times: dict[str, tuple[float, float]] = {}
    for label in labels:
        for name, arr in _trajectory(arrays, label, kind, t, len(robot.joint_names)).items():
            data[name][label] = arr
        # Phases follow the commanded elbow in a simulation (as the simulator reports them).
        q_phase = np.asarray(arrays.get(f"{label}_q_cmd", data["q"][label]), dtype=np.float64)
        flex = elbow_flexion_deg(q_phase[:, robot.elbow_joint], task, robot.elbow_joint)
        data["flex"][label] = np.asarray(flex, dtype=np.float64)
        times[label] = crossing_times(t, data["flex"][label], bounds)
    return data, times


def comparison_from_arrays(
    kind: Kind,
    result_id: int,
    arrays: StoredArrays,
    result: Mapping[str, Any],
    robot: Robot,
    *,
    urdf: str | None = None,
    methods: tuple[str, str] | None = None,
    allowed_roots: tuple[Path, ...] | None = None,
) -> Comparison:
    """Build a :class:`Comparison` from a job's arrays and JSON result.

    Args:
        kind: ``"plan"`` (arrays of ``PlanResult.arrays()``) or ``"simulation"``
            (``SimulationResult.arrays()``).
        result_id: the plan's or simulation's id.
        arrays: ``t`` (T,) and ``<label>_<name>`` arrays in SI units.
        result: the job's JSON result (``to_dict()``), for conditions and metrics.
        robot: the robot, with the payload the job used.
        urdf: the robot's URDF text (default: read from ``robot.urdf_path``).
        methods: two planned methods to show as ``standard`` and ``optimized`` (their
            ``<method>_*`` arrays); None: the stored ``standard``/``optimized`` pair (the
            quintic and the paper's method), or, for a plan without the paper's method, the
            quintic and the first other planned method (:func:`default_methods`).
        allowed_roots: folders meshes must lie in (an uploaded robot's folder).

    Raises:
        ComparisonError: an array is missing or has the wrong shape, or a method was not
            planned.
        NothingToCompare: no pair was given and the result has no two trajectories.
    """
    if kind not in KINDS:
        raise ComparisonError(f"unknown comparison kind {kind!r} (expected one of {KINDS})")
    if methods is None and not all(f"{label}_q" in arrays for label in LABELS):
        methods = default_methods(arrays)
    if methods is not None:
        arrays = _method_arrays(arrays, methods)
    t = _get(arrays, "t")
    conditions = dict(result.get("conditions") or {})
    task, bounds = _task_and_bounds(conditions, robot)
    planned = tuple(m for m in METHODS if f"{m}_q" in arrays and f"{m}_tau" in arrays)
    if kind == "front" and methods is not None:
        planned = methods  # a point's id is no planning method
    data, times = _curves(arrays, (*LABELS, *planned), kind, t, robot, task, bounds)
    payload = robot.payload
    return Comparison(
        kind=kind,
        id=int(result_id),
        robot=str(conditions.get("robot", robot.name)),
        joint_names=tuple(robot.joint_names),
        t=t,
        q=data["q"],
        qd=data["qd"],
        qdd=data["qdd"],
        tau=data["tau"],
        power=data["power"],
        energy=data["energy"],
        elbow_flexion_deg=data["flex"],
        phase_bounds_deg=bounds,
        phase_times=times,
        elbow_joint=int(robot.elbow_joint),
        urdf=urdf if urdf is not None else Path(robot.urdf_path).read_text(),
        payload_body=robot.payload_body,
        payload_mass=float(payload.mass),
        payload_com=np.asarray(payload.com, dtype=np.float64),
        payload_size=np.asarray(payload.size, dtype=np.float64),
        result=dict(result),
        shown=methods if methods is not None else ("quintic", "paper"),
        urdf_path=Path(robot.urdf_path),
        package_dirs=tuple(Path(p) for p in robot.package_dirs),
        allowed_roots=allowed_roots,
        locks=dict(robot.locks),
        methods=planned,
        obstacles=workspace_obstacles(robot),
    )


def workspace_obstacles(robot: Robot) -> tuple[dict[str, Any], ...]:
    """The robot's sidecar obstacles as plain data (``Comparison.obstacles``); none when it
    has no sidecar or the sidecar can no longer be read (the viewer then draws none)."""
    import dataclasses

    from app.errors import BioPlanError
    from app.planning.safety import default_scene

    try:
        scene = default_scene(robot)
    except BioPlanError:
        return ()
    return tuple(dataclasses.asdict(o) for o in scene.obstacles)


def default_methods(arrays: StoredArrays) -> tuple[str, str]:
    """The pair shown when none was asked for: the quintic (else the first planned method)
    and the paper's method (else the first other planned one).

    Raises:
        NothingToCompare: fewer than two methods were planned.
    """
    planned = [m for m in METHODS if f"{m}_q" in arrays]
    if len(planned) < 2:
        raise NothingToCompare(
            f"methods: this result has {len(planned)} planned trajectory "
            f"({', '.join(planned) or 'none'}): expected two to compare"
        )
    solid = "quintic" if "quintic" in planned else planned[0]
    ghost = "paper" if "paper" in planned else next(m for m in planned if m != solid)
    return solid, ghost


def _method_arrays(arrays: StoredArrays, methods: tuple[str, str]) -> dict[str, ArrayLike]:
    """``arrays`` with the two methods' ``<method>_*`` arrays as ``standard_*``/``optimized_*``."""
    out = {k: v for k, v in arrays.items() if not k.startswith(LABELS)}
    for label, method in zip(LABELS, methods, strict=True):
        mine = {k[len(method) + 1 :]: v for k, v in arrays.items() if k.startswith(f"{method}_")}
        if f"{method}_q" not in arrays:
            raise ComparisonError(f"method {method!r} was not planned in this result")
        out.update({f"{label}_{name}": v for name, v in mine.items()})
    return out


#: How far below its floor a planned metric may lie by integration error alone (relative): the
#: planner accepts a trapezoidal net work within 0.1 % of ΔPE (``planning.evaluation.
#: check_floors``); a simulation's discrete time steps are allowed 0.5 %
#: (``simulation.comparison.FLOOR_SLACK``). Within it a value is *at* its floor, not below.
FLOOR_TOLERANCE: dict[str, float] = {"plan": 1e-3, "simulation": 5e-3}


def floor_tolerance(kind: str) -> float:
    """The relative tolerance within which a ``kind``'s metric counts as at its floor."""
    return FLOOR_TOLERANCE.get(kind, 1e-3)


def floor_state(value: float | None, floor: float | None, tolerance: float) -> str | None:
    """``"below"``, ``"at"`` or ``"above"`` the floor (None without a value or floor): a value
    within ``tolerance`` (relative) of its floor is at it, whatever the round-off."""
    if value is None or floor is None or not (math.isfinite(value) and math.isfinite(floor)):
        return None
    slack = tolerance * max(abs(floor), 1e-12)
    if value < floor - slack:
        return "below"
    return "at" if value <= floor + slack else "above"


def template_provenance(
    result: Mapping[str, Any],
    *,
    template: Mapping[str, Any] | None = None,
    analysis_id: int | None = None,
    recording: str | None = None,
    inline: bool = False,
) -> dict[str, Any]:
    """Where a comparison's human template came from, and what its angle is, said plainly.

    The planner places the template's peak on the robot's elbow stroke at the same *fraction*
    of the stroke where the person's lifts peak within their own ranges
    (``HumanTemplate.peak_joint_angle``); that angle (``angle_deg``) differs from the mean of
    the lifts' own peak angles (``per_lift_mean_deg`` ± ``per_lift_sd_deg``, what a recording's
    page shows) whenever the robot's stroke is not the lifts' range.

    Args:
        result: the plan's or simulation's JSON result.
        template: the template the plan used (``HumanTemplate.to_dict()``), when known.
        analysis_id: the analysis it came from.
        recording: how to name the recording of that analysis (its label or subject).
        inline: the template was uploaded with the request.

    Returns:
        ``{"paper_default", "source", "angle_deg", "angle_text", "n_lifts",
        "per_lift_mean_deg", "per_lift_sd_deg", "range_fraction", "analysis_id",
        "recording"}``; ``source`` and ``angle_text`` are the sentences to show.
    """
    conditions = result.get("conditions") or {}
    target = result.get("target_peak_velocity_angle_deg")
    if target is None:
        target = conditions.get("target_peak_velocity_angle_deg")
    t = dict(template or {})
    n_lifts = int(t.get("n_lifts", conditions.get("template_lifts") or 0) or 0)
    default = bool(conditions.get("template_is_paper_default", n_lifts == 0))
    paper = n_lifts == 0 if t else default
    angle = "–" if target is None else f"{float(target):.1f}°"
    out: dict[str, Any] = {
        "paper_default": paper,
        "angle_deg": target,
        "n_lifts": 0 if paper else n_lifts,
        "per_lift_mean_deg": None if paper else t.get("peak_velocity_angle_deg"),
        "per_lift_sd_deg": None if paper else t.get("peak_velocity_angle_sd_deg"),
        "range_fraction": None if paper else t.get("peak_velocity_range_fraction"),
        "analysis_id": analysis_id,
        "recording": recording,
    }
    if paper:
        out["source"] = f"the paper's default {angle}, not from the person's lifts"
        out["angle_text"] = (
            f"peak-velocity angle {angle}: the paper's value, placed on the robot's elbow stroke"
        )
        return out
    lifts = f"{n_lifts} lift{'' if n_lifts == 1 else 's'}" if n_lifts else "the lifts"
    whose = recording or (f"analysis #{analysis_id}" if analysis_id is not None else None)
    if whose is None:
        whose = "an uploaded template" if inline else str(conditions.get("template") or "?")
    elif analysis_id is not None and recording:
        whose = f"{recording} (analysis #{analysis_id})"
    out["source"] = f"from {lifts} of {whose}"
    out["angle_text"] = _angle_text(angle, out)
    return out


def _angle_text(angle: str, info: Mapping[str, Any]) -> str:
    """What the template's angle is, beside the lifts' own peaks (what the recording shows)."""
    frac, mean, sd = info["range_fraction"], info["per_lift_mean_deg"], info["per_lift_sd_deg"]
    text = f"template angle {angle} on the robot's elbow stroke"
    if frac is not None:
        text += (
            f" (where the lifts peak on average, {100 * float(frac):.0f} % of the way through"
            " each lift's own range, placed on the robot's stroke)"
        )
    if mean is not None:
        spread = "" if info["n_lifts"] == 1 or sd is None else f" ± {float(sd):.1f}°"
        text += (
            f"; per-lift peaks {float(mean):.1f}°{spread} (mean ± SD of each lift's own peak angle)"
        )
    return text
