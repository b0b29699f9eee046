// The shapes of the API answers the dashboard reads, for `tsc --checkJs` (make lint): a page that
// reads a field not named here is an error. The results' shapes are generated from the server's
// response models (api_types.d.ts, written by scripts/js_types.py from app/api/result_models.py)
// and re-exported here under the names the pages use; the few answers without a model yet are
// written below. Used from JS as `/** @typedef {import("./types").PlanResult} PlanResult */`.

export type {
  ComparisonView,
  FrontConvergence,
  FrontOut,
  FrontPoint,
  FrontReference,
  FrontResult,
  MethodResult,
  MetricInfo,
  PlanOut,
  PlanResult,
  Safety,
  SafetyFinding,
  SweepOut,
  SweepResult,
  TrajectoryCurves,
} from "./api_types";
/** GET /api/meta: the names every page shares (app/names.py `as_json`, app/api/result_models.py `MetaOut`). */
export type Meta = import("./api_types").MetaOut;
/** One page of a list (app/api/schemas.py `Page`), newest first. */
export interface Page<T> {
  items: T[];
  /** Items matching the filters, on all pages. */
  total: number;
  limit: number;
  offset: number;
}
/** A job as the pages read it (app/api/schemas.py `Job`). */
export type JobInfo = import("./api_types").Job;

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

/** GET /api/fronts/{id}/points/{pid}/view: the point and the viewer playing it beside the quintic. */
export interface FrontPointView {
  point: import("./api_types").FrontPoint;
  viewer: { enabled: boolean; url?: string; path?: string; host?: string; port?: number };
}

/** One error of a request the schema refuses (`Problem.errors`). */
export interface ProblemError {
  /** The request field, dotted with list indices ("methods.1"), or null. */
  field?: string | null;
  message?: string | null;
}

/** An API failure's body: application/problem+json (app/api/errors.py). */
export interface Problem {
  type?: string;
  title?: string;
  status?: number;
  detail?: string;
  /** The request field at fault. */
  field?: string;
  /** The uploaded file at fault. */
  file?: string;
  /** Every unreadable file of an upload, each with its message. */
  files?: { file: string; detail: string }[];
  /** Every error of a request the schema refuses, first message per field. */
  errors?: ProblemError[];
  /** The job a 409 is waiting for. */
  job?: import("./api_types").Job;
}

/** A caught error as the pages read it: an Error, or api.js's ApiError with its problem. */
export type CaughtError = { message?: string; problem?: Problem } | null | undefined;

/** A job as the drawer keeps it (GET /api/events/jobs): a job without its parameters, with a
 * line about what it works on and its recording. */
export type JobSummary = Omit<import("./api_types").Job, "params"> & {
  about?: string;
  recording_id?: number | null;
};

/** A robot as GET /api/robots lists it (app/api/schemas.py `RobotInfo`; the fields the pages read). */
export interface RobotInfo {
  name: string;
  builtin: boolean;
  joint_names: string[];
  /** [rad]; null = unbounded */
  q_min: (number | null)[];
  /** [rad]; null = unbounded */
  q_max: (number | null)[];
  /** Default payload [kg]. */
  payload: number | null;
  has_mjcf: boolean;
  missing_meshes?: string[] | null;
  /** The default task's safety check at upload (robot_upload.js `defaultTaskWarning`). */
  default_task_safety?: Record<string, unknown> | null;
  /** The robot and logs an identified version comes from. */
  identified_from?: { robot: string } | null;
}
