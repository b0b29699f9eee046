// The shapes of the API answers the dashboard reads, for `tsc --checkJs` (make lint): a page that
// reads a field not named here is an error. Written from the server's `to_dict`s (their modules
// are named beside each shape); a field the page does not read may be left out. Used from JS as
// `/** @typedef {import("./types").PlanResult} PlanResult */`.

/** One contact of a method's trajectory (app/planning/safety.py `Finding.to_dict`). */
export interface SafetyFinding {
  method: string;
  /** First time in contact [s]. */
  time: number;
  kind: "self" | "plane" | "obstacle";
  links: string[];
  /** "mount plane" or the obstacle's name; null for `self`. */
  obstacle: string | null;
  /** Deepest penetration [m]. */
  depth: number;
  deepest_time: number;
  between_samples: boolean;
}

/** The plan's collision and workspace check (app/planning/safety.py `SafetyReport.to_dict`). */
export interface Safety {
  checked: boolean;
  /** null when not checked. */
  ok: boolean | null;
  /** Why it was not checked (only then). */
  reason?: string;
  /** Smallest signed distance of any checked pair [m], null when not checked. */
  min_clearance: number | null;
  margin: number;
  findings: SafetyFinding[];
  mount_plane_height: number | null;
  obstacles: string[];
  pairs: Record<string, number>;
}

/** One method's metrics and checks (app/planning/methods.py `MethodResult.to_dict`); its metric
 * values are read by name (`names.metrics`), so they are indexed, not listed. */
export interface MethodResult {
  label: string;
  /** Peak torque per joint [Nm]. */
  peak_torque: number[];
  peak_velocity_angle_deg: number | null;
  improvement_pct?: Record<string, number | null>;
  share_of_achievable_pct?: number | null;
  solver?: Record<string, unknown> | null;
}

/** A plan's (or simulation's) result (app/planning/planner.py `PlanResult.to_dict`). */
export interface PlanResult {
  joint_names: string[];
  duration: number;
  standard: MethodResult;
  optimized?: MethodResult;
  /** Every method's result by name (older results: only standard/optimized). */
  methods?: Record<string, MethodResult>;
  /** Physical floors [SI] by metric or floor name; null: no floor. */
  floors?: Record<string, number | null>;
  improvement_pct?: Record<string, number | null>;
  share_of_achievable_pct?: Record<string, number | null>;
  target_peak_velocity_angle_deg?: number | null;
  optimizer?: { iterations: number; stopped_early: boolean } | null;
  /** Simulations carry the planned result's facts here. */
  planned?: { optimizer?: { iterations: number; stopped_early: boolean } | null };
  conditions?: {
    objective?: string;
    payload?: number;
    duration?: number;
    template?: string;
    target_peak_velocity_angle_deg?: number | null;
  };
  warnings?: string[];
  safety?: Safety;
}

/** Sampled curves of one trajectory (app/viewer/comparison.py `Comparison.curves`). */
export interface TrajectoryCurves {
  /** (T, n) lists per joint. */
  q: number[][];
  qd: number[][];
  qdd: number[][];
  tau: number[][];
  power: number[];
  energy: number[];
  elbow_flexion_deg: number[];
  elbow_velocity_normalised: number[];
}

/** GET /api/viewer/comparisons/{kind}/{id} (app/viewer/comparison.py `summary` and `curves`). */
export interface ComparisonView {
  robot: string;
  joint_names: string[];
  elbow_joint: number;
  duration: number;
  payload: { mass: number; body: string; com: number[]; size: number[] };
  phase_times: { standard: (number | null)[]; optimized: (number | null)[] };
  /** The pair shown: standard (solid) and optimized (ghost) method names. */
  methods: { standard: string; optimized: string };
  planned: string[];
  floor_tolerance?: number;
  template?: { source?: string; angle_text?: string };
  human?: {
    shown: boolean;
    note?: string | null;
    lift?: { index?: number; file?: string; start_s?: number; top_s?: number } | null;
  };
  curves: {
    t: number[];
    joint_names: string[];
    standard: TrajectoryCurves;
    optimized: TrajectoryCurves;
    human: { elbow_velocity_normalised: number[] } | null;
  };
  result: PlanResult;
  viewer: { enabled: boolean; host: string; url: string };
  exports: Record<string, string>;
}

/** One channel of a recording's files (GET /api/recordings/{id}), with its file's name. */
export interface RecordingChannel {
  id: number;
  name: string;
  kind: string;
  unit: string;
  /** The mapped muscle site, or null. */
  site: string | null;
  /** Sampling rate [Hz]. */
  rate: number;
  /** Time of the first sample [s]. */
  start: number;
  /** [s] */
  duration: number;
  n_samples: number;
  dims: number;
  flat: boolean;
  excluded: boolean;
  /** The file's original name (set by the page). */
  file?: string;
}

/** One channel's samples from GET /api/recordings/{id}/signals (t, y: down-sampled lists). */
export interface SignalSeries {
  t: number[];
  y: (number | null)[];
}

/** A metric's description (app/names.py `MetricInfo`). */
export interface MetricInfo {
  name: string;
  unit: string;
  label: string;
  formula: string;
  per_joint: boolean;
  /** The floor bounding it from below, or null: no floor. */
  floor: string | null;
}

/** GET /api/meta: the names every page shares (app/names.py `as_json`). */
export interface Meta {
  metrics: MetricInfo[];
  phases: { name: string; label: string; colour: string }[];
  /** The elbow angles [deg] between phases A/B and B/C. */
  phase_bounds_deg: [number, number];
  methods: { name: string; label: string; description: string; colour: string }[];
  /** CSS colour by muscle site. */
  muscle_colours: Record<string, string>;
  pso_defaults: { particles: number; iterations: number; n_samples: number; seed: number };
  job_states: string[];
  terminal_job_states: string[];
}

/** The mesh refinement of one optimal-control solve of a front (app/planning/front.py `_solve`). */
export interface FrontConvergence {
  /** Each mesh solved: its intervals and the objective on it, or why it failed. */
  sequence: { n_intervals: number; objective?: number; error?: string }[];
  /** |change| of the objective between the last two meshes over its value; null: one mesh. */
  relative_change: number | null;
  converged: boolean;
  final_intervals: number;
  tolerance: number;
}

/** One point of a front (app/planning/front.py `FrontPoint.to_dict`); its axis values (every
 * metric of FRONT_AXES and `duration`) are read by name, so they are indexed, not listed. */
export interface FrontPoint {
  id: string;
  /** Peak |τ| by joint name [Nm]. */
  peak_torques: Record<string, number>;
  /** The elbow speed profile's distance to the template's (0 = the same). */
  human_likeness: number;
  /** The bound on B this point was solved under; null at the ends. */
  epsilon: number | null;
  /** "A end", "B end" or null. */
  end: string | null;
  knee: boolean;
  convergence: FrontConvergence;
  violations: string[];
  [axis: string]: unknown;
}

/** A reference method's values at the front's duration, or why it failed there. */
export interface FrontReference {
  error?: string;
  [axis: string]: unknown;
}

/** A front's result (`Front.to_dict` plus the service's `references` and `methods`). */
export interface FrontResult {
  robot: string;
  payload_mass: number;
  /** [A, B]: A is minimised with B <= epsilon. */
  objectives: [string, string];
  method: string;
  /** The fixed duration [s]; null when duration is an axis. */
  duration: number | null;
  rules: string[];
  /** The knee point's id, or null. */
  knee: string | null;
  /** Non-dominated, sorted by A (B falling). */
  points: FrontPoint[];
  shortest_duration: { duration: number; infeasible_below: number | null } | null;
  dropped: Record<string, unknown>[];
  solves: number;
  seconds: number;
  notes: string[];
  /** quintic, paper, jerk_limited: the same metric keys as a point, or `error`. */
  references?: Record<string, FrontReference>;
  /** The ids that can be viewed and exported ("quintic", "p0", ...). */
  methods?: string[];
}

/** A job as the pages read it (app/api/schemas.py `Job`). */
export interface JobInfo {
  id: number;
  kind: string;
  state: string;
  progress: number;
  stage: string;
  done: number;
  of: number;
  message: string;
  error: string | null;
  finished_at: string | null;
  params: Record<string, any>;
  result_url: string;
  events_url: string;
}

/** GET /api/fronts/{id} (app/api/schemas.py `ResultOut`). */
export interface FrontOut {
  id: number;
  robot: string;
  label: string | null;
  job: JobInfo;
  result: FrontResult | null;
}

/** GET /api/fronts/{id}/points/{pid}/view: the point and the viewer playing it beside the quintic. */
export interface FrontPointView {
  point: FrontPoint;
  viewer: { enabled: boolean; url?: string; path?: string; host?: string; port?: number };
}
