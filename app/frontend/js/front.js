// Trade-offs (issue 26), under Compare (#/compare/fronts[/ID]): the Pareto front between two
// metrics, or a metric and the duration, by optimal control (POST /api/fronts, `bioplan front`),
// with progress per point and cancel. The page draws only what the API gives: the points, the
// knee and the ends it marks, and the quintic's, paper's and jerk-limited's points at the
// front's duration (`result.references`). Clicking a point shows its metrics and plays it in the
// viewer beside the quintic; the front exports as CSV and each point as a trajectory like a plan.

import { api, followJob, qs } from "./api.js";
import { EXPORT_FORMATS, download, methodInfo, viewerUrl } from "./compare.js";
import { isTerminal, metric, names } from "./names.js";
import { draw, layout } from "./plots.js";
import { jobProgress } from "./sweep_form.js";
import { banner, clear, clearFieldErrors, fmt, h, messageOf, showCaps, showFormErrors, when } from "./ui.js";

/** @typedef {import("./types").FrontOut} FrontOut */
/** @typedef {import("./types").FrontPoint} FrontPoint */
/** @typedef {import("./types").FrontPointView} FrontPointView */
/** @typedef {import("./types").FrontReference} FrontReference */
/** @typedef {import("./types").FrontResult} FrontResult */
/** @typedef {import("./types").JobInfo} JobInfo */
/** @typedef {ReturnType<typeof formFields>} FrontFields */

/** The methods of a front, their labels from the shared names. */
const FRONT_METHODS = ["bound", "human_optimal"];
/** The reference methods drawn on the front's axes (the service's `references`). */
const REFERENCES = ["quintic", "paper", "jerk_limited"];
/**
 * The front request's fields in the form's words.
 * @type {Record<string, string>}
 */
const FRONT_WORDS = {
  label: "Label", robot: "Robot", payload_mass: "Payload", objectives: "Objectives", method: "Method", points: "Points",
  duration: "Duration", intervals: "Intervals", tolerance: "Tolerance", allow_reversal: "Allow reversal",
  max_duration: "Longest duration",
};
/** @type {Record<string, string>} */
const SYMBOL = { point: "circle", knee: "star", reference: "diamond" };

/**
 * An axis' label and unit.
 * @param {string} name one of the front's axes (`names.front_axes`, from /api/meta)
 * @returns {{ name: string, label: string, unit: string }}
 */
export function axisInfo(name) {
  // Axes a front measures differently from the shared names (or that they do not name), in the
  // server's words (/api/meta `front_axis_text`).
  const own = names.front_axis_text[name];
  if (own) return { name, ...own };
  const m = metric(name);
  return { name, label: m ? m.label : name, unit: m ? m.unit : "" };
}

/**
 * "absolute work [J]"
 * @param {string} name an axis
 * @returns {string}
 */
function axisTitle(name) {
  const a = axisInfo(name);
  return a.unit ? `${a.label} [${a.unit}]` : a.label;
}

/**
 * A value of a point or a reference by axis, or null where it has none.
 * @param {FrontPoint | FrontReference} item
 * @param {string} axis
 * @returns {number | null}
 */
function valueOf(item, axis) {
  const v = /** @type {Record<string, unknown>} */ (/** @type {unknown} */ (item))[axis];
  return typeof v === "number" ? v : null;
}

/**
 * The list's words for a front: its number, label, robot, axes and when it finished.
 * @param {any} item a listed front (GET /api/fronts)
 * @returns {string}
 */
function frontTitle(item) {
  const p = (item.job && item.job.params) || {};
  const r = item.result || {};
  const [a, b] = r.objectives || p.objectives || ["?", "?"];
  const label = item.label ? ` “${item.label}”` : "";
  const count = r.points ? `${r.points.length} points` : item.job.state;
  return `Front #${item.id}${label}: ${item.robot}, ${a} vs ${b}, ${r.method || p.method || "bound"}, ${count} · ${when(item.job.finished_at)}`;
}

// ---- the page --------------------------------------------------------------------------------

/**
 * @param {HTMLElement} main
 * @param {Array<string | undefined>} match the front's id, if any
 */
export async function render(main, [idArg]) {
  /** @type {(() => void)[]} */
  const stops = [];
  /** @type {[import("./types").RobotInfo[], { items: FrontOut[], error?: unknown }]} */
  const [robots, fronts] = await Promise.all([
    api("/api/robots"),
    api(`/api/fronts${qs({ limit: 100 })}`).catch((err) => ({ items: [], error: err })),
  ]);
  const page = pageParts(fronts.items, idArg);
  main.append(page.head);
  if (fronts.error) main.append(banner("error", `The fronts could not be listed: ${messageOf(fronts.error)}`));
  const view = frontView(page.select, stops);
  main.append(h("div", { class: "grid-2" }, frontForm(robots, view.follow), view.plotCard), view.pointCard);
  if (idArg) await view.open(Number(idArg));
  return () => stops.forEach((f) => f());
}

/**
 * The page's head: its title, the previous fronts to reopen and the way back to Compare.
 * @param {FrontOut[]} items the listed fronts
 * @param {string | undefined} idArg the front opened
 */
function pageParts(items, idArg) {
  const select = h("select", { id: "front-select", "aria-label": "Previous fronts" },
    h("option", { value: "" }, items.length ? "Open a previous front…" : "No front yet"),
    items.map((item) => h("option", { value: String(item.id), selected: String(item.id) === idArg }, frontTitle(item))));
  select.addEventListener("change", () => {
    if (select.value) location.hash = `#/compare/fronts/${select.value}`;
  });
  const head = h("div", { class: "page-head" },
    h("h1", {}, "Trade-offs: Pareto fronts"),
    h("div", { class: "actions", style: "min-width:min(100%,520px)" }, select,
      h("a", { class: "button", href: "#/compare" }, "← Compare the planning methods")));
  return { head, select };
}

// ---- the form --------------------------------------------------------------------------------

/**
 * The form: robot, payload, the two axes (never the same), method, points, duration (none
 * when duration is an axis) and the solver's settings. `follow(job)` follows a submitted front.
 * @param {{ name: string, builtin: boolean, payload: number | null }[]} robots
 * @param {(job: JobInfo) => void} follow
 */
function frontForm(robots, follow) {
  const f = formFields(robots);
  const error = h("div", { id: "front-form-error" });
  const submit = h("button", { type: "submit", class: "primary", id: "submit-front" }, "Draw the front");
  /** @param {SubmitEvent} e */
  const onSubmit = async (e) => {
    e.preventDefault();
    clear(error);
    clearFieldErrors(f.byField);
    submit.disabled = true;
    try {
      follow(await api("/api/fronts", { method: "POST", body: requestOf(f) }));
    } catch (err) {
      showFormErrors(error, err, FRONT_WORDS, f.byField);
    } finally {
      submit.disabled = false;
    }
  };
  bindAxes(f);
  bindPayload(f, robots);
  showCaps("front", { payload_mass: f.payload, points: f.points, duration: f.duration, intervals: f.intervals, max_duration: f.maxDuration });
  return h("form", { class: "card", id: "front-form", novalidate: true, onsubmit: onSubmit },
    h("h2", {}, "New front"),
    h("p", { class: "small muted" }, "Each point minimises objective A with B held below a bound, by optimal control converged on the mesh; the two ends are the single-objective optima. With duration as an axis the front runs from the shortest feasible duration."),
    error,
    h("div", { class: "fields" },
      field("front-robot", "Robot", f.robot), field("front-payload", "Payload", f.payload, "[kg]"),
      field("front-a", "Objective A (minimised)", f.a), field("front-b", "Objective B (bounded)", f.b),
      field("front-method", "Method", f.method), field("front-points", "Points", f.points, "ends included"),
      field("front-duration", "Duration", f.duration, "[s]"), field("front-max-duration", "Longest duration", f.maxDuration, "[s], duration axis only"),
      h("div", { class: "wide" }, field("front-label", "Label", f.label))),
    h("details", {}, h("summary", {}, "Solver"),
      h("div", { class: "fields" },
        field("front-intervals", "Intervals (coarsest mesh)", f.intervals), field("front-tolerance", "Tolerance", f.tolerance, "relative change that stops the refinement")),
      h("label", { class: "check" }, f.reversal, "Allow joints to reverse")),
    h("div", { class: "row", style: "margin-top:12px" }, submit));
}

/**
 * A field with its label (and unit or hint).
 * @param {string} id the input's id
 * @param {string} text the label
 * @param {HTMLElement} input
 * @param {string} [hint]
 */
function field(id, text, input, hint = "") {
  return h("div", {}, h("label", { for: id }, `${text} `, hint ? h("span", { class: "hint" }, hint) : null), input);
}

/**
 * The form's inputs, and the same by request field (for the server's refusals).
 * @param {{ name: string, builtin: boolean }[]} robots
 */
function formFields(robots) {
  /** @param {string} chosen */
  const axisOptions = (chosen) => names.front_axes.map((a) => h("option", { value: a, selected: a === chosen }, `${a}: ${axisTitle(a)}`));
  /**
   * @param {string} id
   * @param {Record<string, string>} attrs
   */
  const number = (id, attrs) => h("input", { id, type: "number", step: "any", ...attrs });
  const f = {
    robot: h("select", { id: "front-robot" }, robots.map((r) => h("option", { value: r.name }, r.builtin ? r.name : `${r.name} (uploaded)`))),
    payload: number("front-payload", { min: "0", placeholder: "robot default" }),
    a: h("select", { id: "front-a" }, axisOptions("abs_work")),
    b: h("select", { id: "front-b" }, axisOptions("peak_torque")),
    method: h("select", { id: "front-method" }, FRONT_METHODS.map((m) => h("option", { value: m }, `${m}: ${methodInfo(m).label}`))),
    points: number("front-points", { min: "2", max: "25", step: "1", value: "9" }),
    duration: number("front-duration", { min: "0", value: "1.0" }),
    maxDuration: number("front-max-duration", { min: "0", placeholder: "3 × the shortest" }),
    intervals: number("front-intervals", { min: "8", step: "1", value: "40" }),
    tolerance: number("front-tolerance", { min: "0", value: "0.001" }),
    reversal: h("input", { id: "front-reversal", type: "checkbox" }),
    label: h("input", { id: "front-label", maxlength: "200", placeholder: "optional: names it in the list" }),
  };
  const byField = {
    robot: f.robot, payload_mass: f.payload, objectives: f.b, method: f.method, points: f.points,
    duration: f.duration, intervals: f.intervals, tolerance: f.tolerance, allow_reversal: f.reversal, max_duration: f.maxDuration,
    label: f.label,
  };
  return { ...f, byField };
}

/** A and B are never the same axis (each offers every axis but the other's), and the fixed
 * duration is only asked for when duration is not an axis (the longest duration only then).
 * @param {FrontFields} f
 */
function bindAxes(f) {
  /** @param {HTMLSelectElement} changed */
  const sync = (changed) => {
    const other = changed === f.a ? f.b : f.a;
    if (other.value === changed.value) other.value = names.front_axes.find((x) => x !== changed.value) || "";
    for (const [sel, not] of /** @type {[HTMLSelectElement, string][]} */ ([[f.a, f.b.value], [f.b, f.a.value]])) {
      [...sel.options].forEach((o) => (o.disabled = o.value === not));
    }
    const durationAxis = f.a.value === "duration" || f.b.value === "duration";
    f.duration.disabled = durationAxis;
    f.maxDuration.disabled = !durationAxis;
  };
  f.a.addEventListener("change", () => sync(f.a));
  f.b.addEventListener("change", () => sync(f.b));
  sync(f.a);
}

/**
 * The payload's placeholder says the chosen robot's default.
 * @param {FrontFields} f
 * @param {{ name: string, payload: number | null }[]} robots
 */
function bindPayload(f, robots) {
  const sync = () => {
    const r = robots.find((x) => x.name === f.robot.value);
    f.payload.placeholder = r && r.payload !== null && r.payload !== undefined ? `default ${fmt(r.payload)} kg` : "robot default";
  };
  f.robot.addEventListener("change", sync);
  sync();
}

/**
 * The request from the form: empty numbers are left to the server's defaults.
 * @param {FrontFields} f
 */
function requestOf(f) {
  /** @param {HTMLInputElement} el */
  const num = (el) => (el.disabled || el.value.trim() === "" ? undefined : Number(el.value));
  const body = {
    robot: f.robot.value, payload_mass: num(f.payload), objectives: [f.a.value, f.b.value], method: f.method.value,
    points: num(f.points), duration: num(f.duration), max_duration: num(f.maxDuration), intervals: num(f.intervals),
    tolerance: num(f.tolerance), allow_reversal: f.reversal.checked, label: f.label.value.trim() || undefined,
  };
  return Object.fromEntries(Object.entries(body).filter(([, v]) => v !== undefined));
}

// ---- a front: progress, plot, points ---------------------------------------------------------

/**
 * The front's cards: the plot (with progress while it runs) and the chosen point's metrics,
 * viewer and exports. `open(id)` shows a front; `follow(job)` follows one being drawn.
 * @param {HTMLSelectElement} select the previous fronts (a finished one joins it)
 * @param {(() => void)[]} stops the page's cleanup functions
 */
function frontView(select, stops) {
  const status = h("div", { id: "front-status" });
  const body = h("div", { id: "front-result" }, h("p", { class: "muted" }, "Draw a front or open a previous one: its points, the knee and the reference methods appear here."));
  const plotCard = h("section", { class: "card", id: "front-card" }, h("h2", {}, "The front"), status, body);
  const pointCard = h("section", { class: "card", id: "front-point-card", hidden: true });

  /** @param {number} id the front's id */
  async function open(id) {
    clear(status);
    let out;
    try {
      out = /** @type {FrontOut} */ (await api(`/api/fronts/${id}`));
    } catch (err) {
      status.append(banner("error", `Front #${id}: ${messageOf(err)}`));
      return;
    }
    if (out.result) await show(out, out.result);
    else if (!isTerminal(out.job.state)) follow(out.job);
    else status.append(banner("error", `Front #${id} ${out.job.state}: ${out.job.error || "no result"}`));
  }

  /** @param {JobInfo} job */
  function follow(job) {
    const box = jobProgress(job, `Front #${job.id}`, { progress: "front-progress", state: "front-state", detail: "front-points-done" },
      (j) => (j.stage === "front" ? `point ${j.done} of ${j.of} · ${j.message}` : j.error || j.message));
    const cancel = h("button", { type: "button", class: "danger small", id: "front-cancel" }, "Cancel");
    cancel.addEventListener("click", () => cancelJob(job.id, cancel, status));
    clear(status).append(box.element, cancel);
    const watch = followJob(job, box.update);
    stops.push(watch.stop);
    watch.done.then(async (final) => {
      cancel.remove();
      const failed = box.finish(final);
      if (failed) return status.append(failed);
      history.replaceState(null, "", `#/compare/fronts/${final.id}`);
      if (![...select.options].some((o) => o.value === String(final.id))) select.append(h("option", { value: String(final.id) }, `Front #${final.id} (just drawn)`));
      select.value = String(final.id);
      return open(final.id);
    });
  }

  /** @param {FrontOut} out @param {FrontResult} r */
  async function show(out, r) {
    const plot = h("div", { class: "plot tall", id: "front-plot" });
    const choose = pointChooser(out.id, r, body, pointCard, (pid) => drawFront(plot, r, pid));
    clear(body).append(frontFacts(out, r), referenceNotes(r), plot, exportsRow(out.id), pointsTable(r, choose));
    const div = await drawFront(plot, r);
    div.on("plotly_click", (event) => {
      const pid = event.points && event.points[0] && event.points[0].customdata;
      if (pid) choose(String(pid));
    });
    await choose(r.knee || (r.points[0] && r.points[0].id));
  }

  return { open, follow, plotCard, pointCard };
}

/**
 * POST the job's cancel; a refusal is said in `status`.
 * @param {number} id the job's id
 * @param {HTMLButtonElement} button
 * @param {HTMLElement} status
 */
async function cancelJob(id, button, status) {
  button.disabled = true;
  try {
    await api(`/api/jobs/${id}/cancel`, { method: "POST" });
  } catch (err) {
    status.append(banner("error", messageOf(err)));
    button.disabled = false;
  }
}

/** @param {FrontOut} out @param {FrontResult} r */
function frontFacts(out, r) {
  const [a, b] = r.objectives;
  /**
   * @param {string} k
   * @param {string | Node} v
   * @param {string} [id]
   */
  const fact = (k, v, id) => h("div", { class: "fact" }, h("div", { class: "k" }, k), h("div", { class: "v", style: "font-size:14px", id }, v));
  return h("div", {},
    h("div", { class: "facts", id: "front-facts" },
      fact("robot", r.robot), fact("payload", `${fmt(r.payload_mass)} kg`),
      fact("objectives", `A ${a} · B ${b}`), fact("method", methodInfo(r.method).label),
      fact("duration", r.duration === null ? "an axis" : `${fmt(r.duration)} s`),
      r.shortest_duration ? fact("shortest feasible", `${fmt(r.shortest_duration.duration)} s`, "front-shortest") : null,
      fact("points", String(r.points.length), "front-count"), fact("knee", r.knee || "none", "front-knee"),
      fact("solves", `${r.solves} in ${fmt(r.seconds, 3)} s`)),
    h("p", { class: "small muted" }, `Rules every point keeps: ${r.rules.join(", ")}.`,
      r.dropped.length ? ` ${r.dropped.length} solved point(s) dropped (dominated or failed).` : ""),
    r.notes.length ? h("ul", { class: "small" }, r.notes.map((n) => h("li", {}, n))) : null,
    out.label ? h("p", { class: "small" }, `Label: ${out.label}`) : null);
}

/** Where a reference method is not on the plot, and why. @param {FrontResult} r */
function referenceNotes(r) {
  const refs = r.references || {};
  const [a, b] = r.objectives;
  const missing = REFERENCES.map((m) => {
    const ref = refs[m];
    if (!ref) return `${methodInfo(m).label}: not given for this front`;
    if (ref.error) return `${methodInfo(m).label}: ${ref.error}`;
    if (valueOf(ref, a) === null || valueOf(ref, b) === null) return `${methodInfo(m).label}: no ${valueOf(ref, a) === null ? a : b} value`;
    return null;
  }).filter(Boolean);
  return h("div", { id: "front-ref-notes", class: "small muted" },
    missing.length ? ["Not drawn: ", h("ul", {}, missing.map((t) => h("li", { dataset: { missing: "" } }, t)))] : null);
}

/**
 * The front, its knee, its labelled ends and the reference methods on A (x) and B (y), with a
 * ring around the chosen point.
 * @param {HTMLElement} div
 * @param {FrontResult} r
 * @param {string | null} [chosen] a point's id
 * @returns {Promise<PlotlyElement>}
 */
async function drawFront(div, r, chosen = null) {
  const [a, b] = r.objectives;
  const pts = r.points;
  /** @param {string} who */
  const hover = (who) => `${who}<br>${a} %{x}<br>${b} %{y}<extra></extra>`;
  /** @type {Record<string, any>[]} Plotly traces */
  const traces = [{
    x: pts.map((p) => valueOf(p, a)), y: pts.map((p) => valueOf(p, b)), customdata: pts.map((p) => p.id),
    text: pts.map((p) => (p.end ? `${p.end}: least ${p.end.startsWith("A") ? a : b}` : "")), textposition: "top right",
    mode: "lines+markers+text", name: `front (${methodInfo(r.method).label})`, hovertemplate: hover("%{customdata}"),
    marker: { size: 10, symbol: SYMBOL.point, color: methodInfo(r.method).colour }, line: { color: methodInfo(r.method).colour, width: 1.5 },
  }];
  const knee = pts.find((p) => p.knee);
  if (knee) {
    traces.push({ x: [valueOf(knee, a)], y: [valueOf(knee, b)], customdata: [knee.id], mode: "markers", name: "knee", hovertemplate: hover("knee %{customdata}"),
      marker: { size: 20, symbol: SYMBOL.knee, color: "#f59f00", line: { color: "#111827", width: 1 } } });
  }
  traces.push(...referenceTraces(r, hover));
  const marked = chosen ? pts.find((p) => p.id === chosen) : null;
  if (marked) {
    traces.push({ x: [valueOf(marked, a)], y: [valueOf(marked, b)], mode: "markers", name: "chosen", showlegend: false, hoverinfo: "skip",
      marker: { size: 26, symbol: "circle-open", color: "#111827", line: { width: 2 } } });
  }
  await draw(div, traces, layout({
    height: 440, hovermode: "closest", margin: { l: 70, r: 20, t: 40, b: 50 },
    xaxis: { title: { text: `A: ${axisTitle(a)}` }, gridcolor: "#eceff3" },
    yaxis: { title: { text: `B: ${axisTitle(b)}` }, gridcolor: "#eceff3" },
  }));
  return /** @type {PlotlyElement} */ (div);
}

/** One marker per reference method that has both values (not clickable: the viewer plays a
 * point beside the quintic). @param {FrontResult} r @param {(who: string) => string} hover */
function referenceTraces(r, hover) {
  const [a, b] = r.objectives;
  const refs = r.references || {};
  return REFERENCES.filter((m) => refs[m] && !refs[m].error && valueOf(refs[m], a) !== null && valueOf(refs[m], b) !== null).map((m) => ({
    x: [valueOf(refs[m], a)], y: [valueOf(refs[m], b)],
    mode: "markers", name: methodInfo(m).label, hovertemplate: hover(methodInfo(m).label),
    marker: { size: 13, symbol: SYMBOL.reference, color: methodInfo(m).colour, line: { color: "#111827", width: 1 } },
  }));
}

/**
 * The front's points as a table (each row chooses its point, as a click on the plot does).
 * @param {FrontResult} r
 * @param {(pid: string | null) => Promise<void>} choose
 */
function pointsTable(r, choose) {
  const [a, b] = r.objectives;
  const rows = r.points.map((p) => h("tr", { class: "click", tabindex: "0", dataset: { point: p.id }, onclick: () => choose(p.id),
    onkeydown: (/** @type {KeyboardEvent} */ e) => (e.key === "Enter" ? choose(p.id) : null) },
  h("td", { class: "mono" }, p.id), h("td", { class: "num" }, fmt(valueOf(p, a))), h("td", { class: "num" }, fmt(valueOf(p, b))),
  h("td", {}, [p.knee ? "knee" : "", p.end || ""].filter(Boolean).join(", "))));
  return h("details", { class: "table-wrap" }, h("summary", {}, `The ${r.points.length} points`),
    h("table", { id: "front-points-table" },
      h("thead", {}, h("tr", {}, h("th", {}, "point"), h("th", { class: "num" }, axisTitle(a)), h("th", { class: "num" }, axisTitle(b)), h("th", {}, ""))),
      h("tbody", {}, rows)));
}

/**
 * The front's CSV.
 * @param {number} id the front's id
 */
function exportsRow(id) {
  const status = h("span", { class: "small muted", id: "front-csv-status", role: "status" });
  const csv = h("a", { class: "button small", id: "front-csv", href: `/api/fronts/${id}/csv` }, "Front as CSV");
  csv.addEventListener("click", (e) => {
    e.preventDefault();
    download(csv.href, csv, status);
  });
  return h("div", { class: "row", style: "margin:8px 0" }, csv, status,
    h("span", { class: "small muted" }, "Click a point (or a row below) to see its metrics and play it beside the quintic."));
}

// ---- the chosen point ------------------------------------------------------------------------

/**
 * Choosing a point: its view from the API, its metrics, the viewer playing it and its exports.
 * Answers that arrive after a later choice are dropped.
 * @param {number} id the front
 * @param {FrontResult} r
 * @param {HTMLElement} body the front's card: its plot and table rows are marked with the choice
 * @param {HTMLElement} card where the point is shown
 * @param {(pid: string) => Promise<unknown>} mark marks the chosen point on the plot
 * @returns {(pid: string | null) => Promise<void>}
 */
function pointChooser(id, r, body, card, mark) {
  let latest = "";
  const frame = h("iframe", { class: "viewer-frame", id: "front-viewer-frame", title: "3-D viewer: the point beside the quintic", allow: "fullscreen" });
  /** @param {string | null} pid */
  async function choose(pid) {
    if (!pid) return;
    latest = pid;
    body.dataset.selected = pid;
    body.querySelectorAll("tr[data-point]").forEach((tr) => tr.classList.toggle("chosen", /** @type {HTMLElement} */ (tr).dataset.point === pid));
    let view;
    try {
      view = /** @type {FrontPointView} */ (await api(`/api/fronts/${id}/points/${encodeURIComponent(pid)}/view`));
    } catch (err) {
      if (latest === pid) showPointError(card, pid, err);
      return;
    }
    if (latest !== pid) return;
    clear(card).append(h("h2", {}, `Point ${pid}`, view.point.knee ? " (the knee)" : "", view.point.end ? ` (${view.point.end})` : ""),
      h("div", { class: "grid-2" }, pointMetrics(r, view.point), viewerBox(view.viewer, frame, pid)), pointExports(id, pid));
    card.hidden = false;
    await mark(pid);
  }
  return choose;
}

/**
 * @param {HTMLElement} card
 * @param {string} pid the point's id
 * @param {unknown} err what was caught
 */
function showPointError(card, pid, err) {
  clear(card).append(h("h2", {}, `Point ${pid}`), banner("error", messageOf(err)));
  card.hidden = false;
}

/**
 * Every metric of the point, its peak torques, human-likeness and convergence.
 * @param {FrontResult} r
 * @param {FrontPoint} p
 */
function pointMetrics(r, p) {
  const [a, b] = r.objectives;
  /**
   * @param {string} name
   * @param {string} text
   * @param {number | null | undefined} value
   * @param {string} [cls]
   */
  const row = (name, text, value, cls = "") => h("tr", { class: cls, dataset: { metric: name, value: value ?? "" } }, h("td", {}, text), h("td", { class: "num" }, fmt(value)));
  const axes = [a, b, ...names.front_axes.filter((x) => x !== a && x !== b)];
  return h("div", { id: "front-point-metrics", dataset: { point: p.id } },
    h("table", { id: "front-point-table" }, h("tbody", {},
      axes.map((x) => row(x, `${x === a ? "A " : x === b ? "B " : ""}${axisTitle(x)}`, valueOf(p, x), x === a || x === b ? "objective-row" : "")),
      row("human_likeness", "human-likeness distance (0: the template's profile)", p.human_likeness),
      p.epsilon === null ? null : row("epsilon", `bound on ${b} it was solved under`, p.epsilon))),
    torqueTable(p.peak_torques), convergenceText(p),
    p.violations.length ? banner("error", `Limits broken: ${p.violations.join("; ")}`) : null);
}

/** @param {Record<string, number | null>} peaks by joint [Nm] */
function torqueTable(peaks) {
  const joints = Object.keys(peaks);
  return h("div", { class: "table-wrap", style: "margin-top:10px" }, h("table", { id: "front-point-torques" },
    h("thead", {}, h("tr", {}, h("th", {}, "peak torque [Nm]"), joints.map((j) => h("th", { class: "num mono" }, j)))),
    h("tbody", {}, h("tr", {}, h("td", {}, "max |τ|"), joints.map((j) => h("td", { class: "num", dataset: { joint: j } }, fmt(peaks[j])))))));
}

/** @param {FrontPoint} p */
function convergenceText(p) {
  const c = p.convergence;
  const meshes = c.sequence.map((s) => (s.error ? `${s.n_intervals} (failed)` : String(s.n_intervals))).join(" → ");
  const verdict = c.converged ? "converged" : "NOT converged";
  return h("p", { class: `small ${c.converged ? "muted" : "worse"}`, id: "front-point-convergence" },
    `${verdict}: meshes ${meshes} intervals; last change ${fmt(c.relative_change)} (tolerance ${fmt(c.tolerance)}).`);
}

/**
 * The viewer playing the point beside the quintic, or why there is none.
 * @param {FrontPointView["viewer"]} viewer
 * @param {HTMLIFrameElement} frame kept between points, so only its address changes
 * @param {string} pid
 */
function viewerBox(viewer, frame, pid) {
  if (!viewer.enabled || !viewer.url) {
    return h("div", { id: "front-viewer" }, banner("info", "The 3-D viewer is not running on this server; the metrics and exports still work."));
  }
  const url = viewerUrl({ host: viewer.host || "", url: viewer.url });
  if (frame.getAttribute("src") !== url) frame.src = url;
  frame.dataset.point = pid;
  return h("div", { id: "front-viewer" }, frame,
    h("p", { class: "small muted" }, `${pid} beside the standard quintic at the same duration. `,
      h("a", { href: url, target: "_blank", rel: "noopener" }, "Open the viewer alone ↗")));
}

/**
 * The point's trajectory in every format a plan exports.
 * @param {number} id the front's id
 * @param {string} pid the point's id
 */
function pointExports(id, pid) {
  const status = h("span", { class: "small muted", id: "front-point-export-status", role: "status" });
  const rate = h("input", { id: "front-export-rate", type: "number", min: "1", max: "10000", step: "any", placeholder: "format's default", "aria-label": "Sample rate [Hz]", style: "width:140px" });
  const links = EXPORT_FORMATS.map(([format, text]) => {
    const a = h("a", { class: "button small", dataset: { format }, href: "" }, text);
    a.addEventListener("click", (e) => {
      e.preventDefault();
      download(a.href, a, status);
    });
    return a;
  });
  const setHrefs = () => links.forEach((a) => (a.href = `/api/fronts/${id}/points/${encodeURIComponent(pid)}/export${qs({ format: a.dataset.format, rate: rate.value })}`));
  rate.addEventListener("input", setHrefs);
  setHrefs();
  return h("div", { id: "front-point-exports", style: "margin-top:10px" },
    h("h3", {}, `Export ${pid} as a trajectory`),
    h("div", { class: "row" }, links, h("label", { class: "small" }, "rate [Hz] ", rate), status),
    h("p", { class: "small muted" }, "The same formats, limits and safety checks as a plan's exports (docs/export.md)."));
}
