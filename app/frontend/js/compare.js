// Compare: every planned method side by side. The metrics table has a column per method, each
// metric with its physical floor (a value below one is flagged; within the integration's
// tolerance, `floor_tolerance`, it is "at the floor"), the share of the achievable
// saving and the peak torques; the curves per joint draw every method; the recorded human's
// elbow velocity is drawn over the robots'; any two methods go to the 3-D viewer; exports of any
// method in the formats controllers read.

import { api, qs, token } from "./api.js";
import { names } from "./names.js";
import { draw, layout, phaseLabels, phaseLegend, phaseShapes, plotly } from "./plots.js";
import { banner, fmt, h, messageOf, pct, when } from "./ui.js";

/** @typedef {import("./types").ComparisonView} ComparisonView */
/** @typedef {import("./types").PlanResult} PlanResult */
/** @typedef {import("./types").Safety} Safety */
/** @typedef {import("./types").TrajectoryCurves} TrajectoryCurves */

// The floors' formulas and older results' floor names come from /api/meta (names.floor_formulas,
// names.legacy_floor_keys): the page prints them, it never writes them.
// Said plainly where a metric has no physical floor (tau_sq, peak_torque, torque_change).
const NO_FLOOR = "no floor";
/** The trajectory formats a plan exports in ([format, what it is]); a front's points too (front.js). */
export const EXPORT_FORMATS = [
  ["csv", "CSV (t, q, qd, qdd, tau per joint)"], ["json", "JSON"], ["yaml", "YAML (ROS 2 JointTrajectory)"],
  ["mcap", "MCAP (rosbag2)"], ["script", "URScript"], ["mot", "OpenSim .mot"],
];
/** The curves drawn per joint, each a (T, n) field of the trajectory's curves (the server
 * derives joint_power and joint_energy, app/planning/curves.py). */
const CURVES = /** @type {const} */ (["qd", "tau", "joint_power", "joint_energy"]);

/**
 * A method's name, label and colour (grey for one the server does not name).
 * @param {string} name
 * @returns {{ name: string, label: string, colour: string, description?: string }}
 */
export function methodInfo(name) {
  return names.methods.find((m) => m.name === name) || { name, label: name, colour: "#6b7280" };
}

/**
 * [floor value, floor key] of a metric in a result's floors, or [null, null].
 * @param {Record<string, unknown>} floors the result's `floors` [SI]
 * @param {import("./types").MetricInfo} metric
 * @returns {[number | null, string | null]}
 */
function floorOf(floors, metric) {
  if (metric.floor === null) return [null, null];
  for (const key of [metric.name, metric.floor, names.legacy_floor_keys[metric.name]]) {
    const value = key ? floors[key] : undefined;
    if (key && typeof value === "number") return [value, key];
  }
  return [null, null];
}

/** "below", "at" or "above" its floor (null without one). Within `tolerance` (relative: the
 * integration error the planner or simulator accepts, sent as `floor_tolerance`) a value is at
 * its floor: 159.79 against 159.8 is round-off, not an impossible number.
 * @param {unknown} value the method's value [SI]
 * @param {number | null} floor
 * @param {number} tolerance relative
 * @returns {"below" | "at" | "above" | null}
 */
function floorState(value, floor, tolerance) {
  if (floor === null || typeof value !== "number") return null;
  const slack = tolerance * Math.max(Math.abs(floor), 1e-12);
  if (value < floor - slack) return "below";
  return value <= floor + slack ? "at" : "above";
}

/**
 * What tells one comparison from another in the picker.
 * @param {import("./types").PlanOut} item a plan or simulation as listed
 * @param {string} kind "plan" or "simulation"
 * @returns {string}
 */
export function title(item, kind) {
  const c = (item.result && item.result.conditions) || {};
  const p = item.job.params || {};
  const planned = (item.result && item.result.methods && Object.keys(item.result.methods)) || [];
  const what = kind === "simulation" ? "Simulation" : "Plan";
  const label = item.label ? ` “${item.label}”` : "";
  const template = p.template_analysis_id ? `, template of analysis #${p.template_analysis_id}` : "";
  return `${what} #${item.id}${label}: ${item.robot}, ${c.payload ?? p.payload ?? "default"} kg, ${c.duration ?? p.duration} s, ${c.objective ?? p.objective}, ${planned.length || 2} methods${template} · ${when(item.job.finished_at)}`;
}

/**
 * Rename the shown comparison (PATCH its label); the picker shows the new name at once.
 * @param {Choice} selected
 * @param {string} kind
 * @param {HTMLSelectElement} picker
 */
function renameForm(selected, kind, picker) {
  const input = h("input", { id: "label-input", maxlength: "200", placeholder: "label (optional)", value: selected.item.label || "", "aria-label": "Label" });
  const status = h("span", { class: "small muted", id: "label-status" });
  /** @param {Event} e */
  const save = async (e) => {
    e.preventDefault();
    try {
      const out = await api(`/api/${kind}s/${selected.item.id}`, { method: "PATCH", body: { label: input.value } });
      selected.item.label = out.label;
      input.value = out.label || "";
      picker.selectedOptions[0].textContent = title(selected.item, kind);
      status.textContent = out.label ? "renamed" : "label removed";
    } catch (err) {
      status.textContent = messageOf(err);
    }
  };
  return h("form", { class: "row", id: "label-form", style: "margin-top:6px", onsubmit: save },
    input, h("button", { type: "submit", class: "small", id: "label-save" }, "Rename"), status);
}

/** Curves of every planned method: the shown pair's, plus those of the others (fetched as
 * further pairs, since one answer carries two). */
/**
 * @param {string} base the comparison's URL
 * @param {ComparisonView} data
 * @returns {Promise<Record<string, TrajectoryCurves>>} by method name
 */
async function allCurves(base, data) {
  const out = { [data.methods.standard]: data.curves.standard, [data.methods.optimized]: data.curves.optimized };
  const rest = data.planned.filter((m) => !(m in out));
  /** @type {[string, string][]} */
  const pairs = [];
  for (let i = 0; i < rest.length; i += 2) pairs.push([rest[i], rest[i + 1] ?? data.methods.standard]);
  /** @type {ComparisonView[]} */
  const answers = await Promise.all(pairs.map((pair) => api(`${base}${qs({ points: 400, methods: pair.join(",") })}`)));
  answers.forEach((a, i) => {
    out[pairs[i][0]] = a.curves.standard;
    out[pairs[i][1]] = a.curves.optimized;
  });
  return out;
}

/** A comparison the picker offers: a plan or simulation as listed. */
/** @typedef {{ kind: string, item: import("./types").PlanOut }} Choice */

/**
 * @param {HTMLElement} main
 * @param {(string | undefined)[]} args the route's kind, id and query
 */
export async function render(main, [kindArg, idArg, query]) {
  const params = new URLSearchParams(query || "");
  const methodsArg = params.get("methods") || undefined;
  const sweepArg = params.get("sweep");
  /** @typedef {import("./types").Page<import("./types").PlanOut>} PlanPage */
  /** @type {[PlanPage, PlanPage, import("./types").Page<import("./types").SweepOut>, any]} */
  const [plans, sims, sweeps, chosenSweep] = await Promise.all([
    api(`/api/plans${qs({ state: "succeeded", limit: 100 })}`),
    api(`/api/simulations${qs({ state: "succeeded", limit: 100 })}`),
    api(`/api/sweeps${qs({ state: "succeeded", limit: 5 })}`).catch(() => ({ items: [] })),
    // ?sweep=ID: that sweep's heat maps (any sweep, not only the newest of a robot).
    sweepArg ? api(`/api/sweeps/${encodeURIComponent(sweepArg)}`).catch((err) => ({ error: err })) : null,
  ]);
  const options = [
    ...sims.items.map((x) => ({ kind: "simulation", item: x })),
    ...plans.items.map((x) => ({ kind: "plan", item: x })),
  ].sort((a, b) => b.item.id - a.item.id);

  const head = h("div", { class: "page-head" }, h("h1", {}, "Compare the planning methods"),
    h("a", { class: "button small", id: "open-fronts", href: "#/compare/fronts" }, "Trade-offs: Pareto fronts →"));
  main.append(head);
  if (!options.length) {
    main.append(banner("info", "No finished plan or simulation yet. "), h("a", { class: "button primary", href: "#/plan" }, "Plan one"));
    return;
  }
  let kind = kindArg;
  let id = Number(idArg);
  const wanted = chosenSweep && !chosenSweep.error ? chosenSweep : null;
  if (chosenSweep && chosenSweep.error) main.append(banner("warn", `Sweep #${sweepArg}: ${messageOf(chosenSweep.error)}`));
  if (wanted && !kind) {
    // Beside the newest comparison of the sweep's robot (or the newest of all when none).
    const same = options.find((o) => o.item.robot === wanted.robot);
    if (same) ({ kind, item: { id } } = same);
  }
  if (!kind || !options.some((o) => o.kind === kind && o.item.id === id)) {
    if (kind) main.append(banner("warn", `${kind} #${idArg} is not a finished comparison; showing the newest.`));
    ({ kind } = options[0]);
    id = options[0].item.id;
  }
  // Found: kind and id were just set to an offered comparison.
  const selected = /** @type {Choice} */ (options.find((o) => o.kind === kind && o.item.id === id));
  const picker = h("select", { id: "comparison-select", "aria-label": "Comparison" },
    options.map((o) => h("option", { value: `${o.kind}/${o.item.id}`, selected: o.kind === kind && o.item.id === id }, title(o.item, o.kind))));
  picker.addEventListener("change", () => (location.hash = `#/compare/${picker.value}`));
  head.append(h("div", { class: "actions", style: "min-width:min(100%,520px)" }, picker, renameForm(selected, kind, picker)));

  const base = `/api/viewer/comparisons/${kind}/${id}`;
  let data;
  let curvesOf;
  try {
    data = await api(`${base}${qs({ points: 400, methods: methodsArg })}`);
    curvesOf = await allCurves(base, data);
  } catch (err) {
    main.append(banner("error", messageOf(err)));
    return;
  }
  const result = data.result;
  const planned = data.planned;
  const pair = [data.methods.standard, data.methods.optimized];

  const optimizer = result.optimizer || (result.planned && result.planned.optimizer);
  if (optimizer && optimizer.stopped_early) {
    main.append(banner("info", `The paper's method: its PSO stopped early, after ${optimizer.iterations} iterations, because the swarm had stopped improving; the plan is the best it found.`));
  }
  main.append(factsCard(data), metricsCard(kind, result, planned, data.joint_names, data.floor_tolerance ?? 1e-3));

  const curvesCard = h("section", { class: "card", id: "curves-card" });
  const humanCard = h("section", { class: "card", id: "human-card" });
  main.append(curvesCard, humanCard);
  await plotly();
  await drawCurves(curvesCard, data, curvesOf, pair);
  await drawHuman(humanCard, data, curvesOf);

  const sweep = wanted || sweeps.items.find((s) => s.robot === data.robot);
  if (sweep) {
    const card = sweepCard(sweep);
    main.append(card);
    if (wanted) card.scrollIntoView({ block: "start" });
  }
  main.append(viewerCard(kind, id, data, pair), exportCard(kind, id, data, pair));
}

/** @param {ComparisonView} data */
function factsCard(data) {
  const result = data.result;
  const cond = result.conditions || {};
  const warnings = result.warnings || [];
  return h("section", { class: "card" },
    h("div", { class: "facts" },
      fact("robot", data.robot),
      fact("payload", `${fmt(data.payload.mass)} kg`),
      fact("duration", `${fmt(data.duration)} s`),
      fact("objective", cond.objective || "–"),
      fact("methods planned", data.planned.map((m) => methodInfo(m).label).join(", ")),
      fact("human template", templateSource(data.template || {}, result), "template-source"),
      result.safety ? fact("safety", safetyText(result.safety), "plan-safety") : null,
    ),
    h("p", { class: "small", id: "template-angle", style: "margin:8px 0 0" }, (data.template || {}).angle_text || ""),
    warnings.length ? h("details", { class: "small", style: "margin-top:8px" }, h("summary", {}, `${warnings.length} warning(s)`), h("ul", {}, warnings.map((w) => h("li", {}, w)))) : null,
  );
}

/**
 * The plan's collision and workspace check in one line (docs/robots.md): ok with the smallest
 * clearance, the first contact, or why it was not checked (never "ok" then).
 * @param {Safety} safety the plan result's `safety` block
 * @returns {string}
 */
export function safetyText(safety) {
  if (safety.checked !== true) return safety.reason || "not checked";
  const findings = safety.findings || [];
  // No clearance when no pair was near (as the server's summary: n/a, never "0 mm").
  const clearance = safety.min_clearance === null || safety.min_clearance === undefined ? "n/a" : `${fmt(1000 * safety.min_clearance, 3)} mm`;
  if (safety.ok === true || !findings.length) return `ok, min clearance ${clearance}`;
  const f = findings[0];
  const links = (f.links || []).join(" and ");
  const what = f.kind === "self" ? `${links} touch` : `${links} into ${f.obstacle}`;
  const more = findings.length > 1 ? ` (+${findings.length - 1} more)` : "";
  return `UNSAFE: ${methodInfo(f.method).label}, ${what} at ${fmt(f.time, 3)} s, ${fmt(1000 * f.depth, 3)} mm deep${more}`;
}

/** Where the template came from, in the card itself: the paper's default or whose lifts. */
/**
 * @param {{ source?: string | null }} template
 * @param {PlanResult} result
 */
function templateSource(template, result) {
  if (template.source) return template.source;
  const target = result.target_peak_velocity_angle_deg ?? (result.conditions || {}).target_peak_velocity_angle_deg;
  return `${(result.conditions || {}).template || "the paper's default"}, peak at ${fmt(target, 3)}°`;
}

/**
 * @param {string} k
 * @param {string | Node} v
 * @param {string} [id]
 */
function fact(k, v, id) {
  return h("div", { class: "fact" }, h("div", { class: "k" }, k), h("div", { class: "v", style: "font-size:14px", id }, v));
}

/** @param {string} name */
function methodHead(name) {
  const m = methodInfo(name);
  return h("th", { class: "num", dataset: { method: name }, title: m.description || "" },
    h("span", { class: "swatch", style: `background:${m.colour}` }), m.label);
}

/** One row per metric, one column per method; the floor beside; below-floor values flagged. */
/**
 * @param {string} kind "plan" or "simulation"
 * @param {PlanResult} result
 * @param {string[]} planned the methods, in column order
 * @param {string[]} jointNames
 * @param {number} tolerance relative: within it a value is at its floor
 */
function metricsCard(kind, result, planned, jointNames, tolerance) {
  const floors = result.floors || {};
  /** @param {string} name */
  const side = (name) => (result.methods && result.methods[name]) || (name === "quintic" ? result.standard : name === "paper" ? result.optimized : null);
  const objective = (result.conditions || {}).objective;
  const rows = names.metrics.filter((m) => !m.per_joint).map((m) => {
    const [floor, floorKey] = floorOf(floors, m);
    const cells = planned.map((name) => {
      /** @type {Partial<import("./types").MethodResult>} */
      const s = side(name) || {};
      // A metric is a field by its name (names.metrics), beside the ones the model lists.
      const value = /** @type {Record<string, unknown>} */ (/** @type {unknown} */ (s))[m.name];
      const found = name === "quintic" ? null : (s.improvement_pct || {})[m.name];
      const change = typeof found === "number" ? found : null;
      const state = floorState(value, floor, tolerance);
      const below = state === "below";
      return h("td", { class: `num${below ? " below-floor" : ""}`, dataset: { method: name, value: value ?? "", floorState: state ?? "" } },
        value === null || value === undefined ? h("span", { class: "muted", title: "no motor model for this robot" }, "not modelled") : fmt(value),
        change === null || change === undefined ? null : h("div", { class: `small ${change > 0.05 ? "better" : change < -0.05 ? "worse" : "muted"}` }, pct(change)),
        below ? h("div", { class: "worse small", role: "alert" }, "below floor!") : null,
        state === "at" ? h("div", { class: "small muted at-floor", title: `within ${100 * tolerance} % of the floor: the integration's round-off` }, "at the floor") : null);
    });
    const floorText = floorKey === "electrical_energy" && floors.friction_energy ? `${names.floor_formulas.electrical_energy} ${fmt(floors.friction_energy)} J` : (floorKey && names.floor_formulas[floorKey]) ?? floorKey;
    return h("tr", { dataset: { metric: m.name }, class: m.name === objective ? "objective-row" : "" },
      h("td", {}, h("strong", {}, m.name), h("span", { class: "narrow-only" }, ` [${m.unit}]`), m.name === objective ? h("span", { class: "small muted" }, " (objective)") : null, h("div", { class: "small muted" }, m.formula),
        // On a narrow window the unit and floor columns give way to these lines.
        h("div", { class: "small narrow-only floor-inline" }, floor === null ? NO_FLOOR : `floor ${fmt(floor)} ${m.unit}: ${floorText}`)),
      h("td", { class: "wide-only" }, m.unit),
      cells,
      h("td", { class: "num wide-only", dataset: { floor: floor ?? "" } }, floor === null ? h("span", { class: "muted no-floor" }, NO_FLOOR) : [fmt(floor), h("div", { class: "small muted" }, floorText)]),
    );
  });
  const shares = result.share_of_achievable_pct || {};
  const shareRow = h("tr", { dataset: { metric: "share" } },
    h("td", {}, h("strong", {}, "share of the achievable saving"), h("div", { class: "small muted" }, `(quintic − method) / (quintic − bound) on ${objective || "the objective"}`)),
    h("td", { class: "wide-only" }, "%"),
    planned.map((name) => {
      const share = shares[name];
      return h("td", { class: "num", dataset: { method: name, value: share ?? "" } }, typeof share === "number" ? `${share.toFixed(1)} %` : "–");
    }),
    h("td", { class: "wide-only" }, ""));
  const angleRow = h("tr", { dataset: { metric: "peak_velocity_angle_deg" } },
    h("td", {}, h("strong", {}, "elbow peak-velocity angle"), h("div", { class: "small muted" }, `template: ${fmt(result.target_peak_velocity_angle_deg ?? (result.conditions || {}).target_peak_velocity_angle_deg, 3)}°`)),
    h("td", { class: "wide-only" }, "°"),
    planned.map((name) => h("td", { class: "num", dataset: { method: name } }, fmt((side(name) || {}).peak_velocity_angle_deg, 3))),
    h("td", { class: "wide-only" }, ""));
  const anyBelow = rows.some((r) => r.querySelector(".below-floor"));
  return h("section", { class: "card", id: "metrics-card" },
    h("h2", {}, kind === "simulation" ? "Metrics measured in the MuJoCo simulation" : "Metrics of the planned trajectories"),
    anyBelow ? banner("error", "A value is below its physical floor: no rest-to-rest motion can do that, so that number is wrong (a model or integration error); it is flagged in red.") : null,
    h("div", { class: "table-wrap" },
      h("table", { id: "metrics-table" },
        h("thead", {}, h("tr", {}, h("th", {}, "metric"), h("th", { class: "wide-only" }, "unit"), planned.map(methodHead), h("th", { class: "num wide-only" }, "physical floor"))),
        h("tbody", {}, rows, shareRow, angleRow),
      ),
    ),
    h("p", { class: "small muted" }, "Under each value: its change against the standard quintic, 100 (quintic − method) / quintic; positive (green) uses less. " + names.floor_note + " Shares are never above 100 %: the bound is solved from every method's trajectory until none beats it."),
    torqueTable(result, planned, jointNames, side),
  );
}

/**
 * @param {PlanResult} result
 * @param {string[]} planned
 * @param {string[]} jointNames
 * @param {(name: string) => import("./types").MethodResult | null | undefined} side a method's result
 */
function torqueTable(result, planned, jointNames, side) {
  const reference = (side("quintic") || result.standard).peak_torque;
  const joints = jointNames || reference.map((_, i) => `J${i + 1}`);
  return h("div", { class: "table-wrap", style: "margin-top:10px" },
    h("table", { id: "torque-table" },
      h("thead", {}, h("tr", {}, h("th", {}, "peak torque [Nm]"), joints.map((j) => h("th", { class: "num mono" }, j)))),
      h("tbody", {}, planned.map((name) => {
        const values = (side(name) || {}).peak_torque || [];
        return h("tr", { dataset: { method: name } }, h("td", {}, methodInfo(name).label),
          values.map((v, j) => {
            const ref = reference[j];
            const higher = name !== "quintic" && v !== null && ref !== null && ref !== undefined && v > ref * 1.005;
            return h("td", { class: `num${higher ? " worse" : ""}`, title: higher ? "higher than the standard quintic's" : "" }, fmt(v), higher ? " ↑" : "");
          }));
      })),
    ),
    h("p", { class: "small muted" }, "↑ red: a peak torque higher than the standard quintic's (the motors must deliver it)."),
  );
}

/**
 * @param {HTMLElement} card
 * @param {ComparisonView} data
 * @param {Record<string, TrajectoryCurves>} curvesOf by method name
 * @param {string[]} pair the two methods in the viewer
 */
async function drawCurves(card, data, curvesOf, pair) {
  const jointNames = data.curves.joint_names;
  let joint = data.elbow_joint;
  const t = data.curves.t;
  const tEnd = t[t.length - 1];
  const seg = h("div", { class: "seg", role: "group", "aria-label": "Joint" });
  const grid = h("div", { class: "grid-plots", id: "curves" });
  // The plots keep their ids (plot-power, plot-energy) whichever field feeds them.
  const plotId = { qd: "qd", tau: "tau", joint_power: "power", joint_energy: "energy" };
  const divs = Object.fromEntries(CURVES.map((k) => [k, h("div", { class: "plot", id: `plot-${plotId[k]}` })]));
  Object.values(divs).forEach((d) => grid.append(h("div", {}, d)));
  const legend = h("div", { class: "legend-inline", id: "methods-legend" },
    data.planned.map((m) => h("span", {}, h("span", { class: "swatch", style: `background:${methodInfo(m).colour}` }), methodInfo(m).label, pair.includes(m) ? " (in the viewer)" : "")),
    phaseLegend(false), h("span", {}, `(phases of ${methodInfo(pair[1]).label})`));
  const redraw = () => Promise.all(CURVES.map((k) => {
    const j = joint;
    const name = jointNames[j];
    const label = { qd: `${name} velocity [rad/s]`, tau: `${name} torque [Nm]`, joint_power: `${name} power |τ·ω| [W]`, joint_energy: `${name} cumulative energy [J]` }[k];
    const traces = data.planned.map((m) => {
      const c = curvesOf[m];
      const y = c[k].map((r) => r[j]);
      return { x: t, y, mode: "lines", name: methodInfo(m).label, line: { color: methodInfo(m).colour, width: pair.includes(m) ? 2.4 : 1.3 } };
    });
    return draw(divs[k], traces, layout({
      height: 270,
      title: { text: label, font: { size: 13 }, x: 0.01, xanchor: "left" },
      showlegend: false,
      margin: { l: 56, r: 10, t: 34, b: 36 },
      xaxis: { title: { text: "t [s]" }, gridcolor: "#eceff3", range: [t[0], tEnd] },
      shapes: phaseShapes(data.phase_times.optimized, t[0], tEnd, "x"),
      annotations: phaseLabels(data.phase_times.optimized),
    }));
  }));
  jointNames.forEach((name, j) => {
    seg.append(h("button", { type: "button", class: j === joint ? "on" : "", onclick: () => {
      joint = j;
      seg.querySelectorAll("button").forEach((x, k) => x.classList.toggle("on", k === j));
      redraw();
    } }, name));
  });
  card.append(
    h("div", { class: "row", style: "margin-bottom:8px" }, h("h2", { style: "margin:0" }, "Curves per joint, every method"), h("div", { style: "margin-left:auto; max-width:100%" }, seg)),
    legend, grid);
  await redraw();
}

/** The robots' elbow velocity over its peak, with the recorded human's lift on the same grid. */
/**
 * @param {HTMLElement} card
 * @param {ComparisonView} data
 * @param {Record<string, TrajectoryCurves>} curvesOf by method name
 */
async function drawHuman(card, data, curvesOf) {
  const t = data.curves.t;
  const human = data.curves.human;
  /** @type {Partial<NonNullable<ComparisonView["human"]>>} */
  const info = data.human || {};
  const div = h("div", { class: "plot", id: "plot-human" });
  /** @type {{ x: number[], y: (number | null)[], mode: string, name: string, line: Record<string, string | number> }[]} */
  const traces = data.planned.map((m) => ({
    x: t, y: curvesOf[m].elbow_velocity_normalised, mode: "lines", name: methodInfo(m).label, line: { color: methodInfo(m).colour, width: 1.8 },
  }));
  if (human) traces.push({ x: t, y: human.elbow_velocity_normalised, mode: "lines", name: "recorded human", line: { color: "#111827", width: 2.6, dash: "dash" } });
  const source = human
    ? `The dashed black line: the recorded person's elbow velocity over its peak during ${info.lift ? `lift ${(info.lift.index ?? 0) + 1} of ${info.lift.file ?? "the recording"} (${fmt(info.lift.start_s, 3)}–${fmt(info.lift.top_s, 3)} s of the recording)` : "the template's lift"}, time-normalised to the plan.`
    : `No recorded human to draw: ${info.note || "this comparison used the paper's default template"}.`;
  card.append(
    h("h2", {}, "Elbow velocity: the robots beside the human"),
    h("p", { class: "small muted", id: "human-note" }, source),
    div);
  await draw(div, traces, layout({
    height: 300, showlegend: true, margin: { l: 56, r: 10, t: 40, b: 36 },
    xaxis: { title: { text: "t [s]" }, gridcolor: "#eceff3", range: [t[0], t[t.length - 1]] },
    yaxis: { title: { text: "elbow velocity / its peak" }, gridcolor: "#eceff3" },
  }));
}

/**
 * The viewer's URL as this page can reach it: the viewer listens on its own port; on a wildcard
 * bind the host the page came from.
 * @param {{ host: string, url: string }} viewer an enabled viewer's address from the API
 * @returns {string}
 */
export function viewerUrl(viewer) {
  const host = ["0.0.0.0", "::", ""].includes(viewer.host) ? location.hostname : viewer.host;
  return viewer.url.replaceAll(`${viewer.host}:`, `${host}:`);
}

/**
 * @param {string} kind
 * @param {number} id
 * @param {ComparisonView} data
 * @param {string[]} pair
 */
function viewerCard(kind, id, data, pair) {
  /** @param {string} sid @param {string} value */
  const select = (sid, value) => h("select", { id: sid, "aria-label": sid === "method-a" ? "Solid robot" : "Ghost robot" },
    data.planned.map((m) => h("option", { value: m, selected: m === value }, methodInfo(m).label)));
  const a = select("method-a", pair[0]);
  const b = select("method-b", pair[1]);
  const note = h("span", { class: "small", id: "pair-note" });
  const show = () => {
    if (a.value === b.value) {
      note.textContent = "Choose two different methods.";
      note.className = "small worse";
      return;
    }
    location.hash = `#/compare/${kind}/${id}?methods=${a.value},${b.value}`;
  };
  a.addEventListener("change", show);
  b.addEventListener("change", show);
  const card = h("section", { class: "card", id: "viewer-card" },
    h("div", { class: "row", style: "margin-bottom:8px" },
      h("h2", { style: "margin:0" }, "3-D viewer"),
      h("label", { class: "small" }, "solid ", a), h("label", { class: "small" }, "ghost ", b), note,
      h("span", { class: "small muted" }, `${methodInfo(pair[0]).label} (solid) · ${methodInfo(pair[1]).label} (ghost) · play, pause, speed, scrub and layout in the viewer's panel`),
    ),
  );
  if (data.viewer.enabled) {
    const url = viewerUrl({ host: data.viewer.host || "", url: data.viewer.url || "" });
    card.append(
      h("iframe", { class: "viewer-frame", id: "viewer-frame", src: url, title: "3-D comparison viewer", allow: "fullscreen" }),
      h("p", { class: "small muted" }, "Each tab gets its own scene. ", h("a", { href: url, target: "_blank", rel: "noopener" }, "Open the viewer alone ↗")),
    );
  } else {
    card.append(banner("info", "The 3-D viewer is not running on this server; the exports still work."));
  }
  return card;
}

/**
 * Fetch a file with the API token, show busy and errors on the button, then save it.
 * @param {string} url
 * @param {HTMLButtonElement | HTMLAnchorElement} button what was clicked: disabled (a link:
 *   aria-disabled) and "Preparing…" meanwhile
 * @param {HTMLElement} status where the saved file or the refusal is said
 */
export async function download(url, button, status) {
  const label = button.textContent;
  /** @param {boolean} on */
  const busy = (on) => (button instanceof HTMLButtonElement ? (button.disabled = on) : button.toggleAttribute("aria-disabled", on));
  busy(true);
  button.textContent = "Preparing…";
  status.textContent = "";
  status.className = "small muted";
  try {
    /** @type {Record<string, string>} */
    const headers = token() ? { Authorization: `Bearer ${token()}` } : {};
    const response = await fetch(url, { headers });
    if (!response.ok) {
      let detail = `HTTP ${response.status}`;
      try {
        detail = (await response.json()).detail || detail;
      } catch {
        /* not a problem document */
      }
      throw new Error(detail);
    }
    const disposition = response.headers.get("Content-Disposition") || "";
    const name = (disposition.match(/filename="([^"]+)"/) || [])[1] || "bioplan-export";
    const blob = await response.blob();
    const href = URL.createObjectURL(blob);
    const link = h("a", { href, download: name, class: "export-link" }, `${name} (${fmt(blob.size / 1024, 3)} KB)`);
    link.click();
    status.replaceChildren("Saved: ", link);
  } catch (err) {
    status.textContent = messageOf(err);
    status.className = "small worse";
  } finally {
    busy(false);
    button.textContent = label;
  }
}

/**
 * @param {string} kind
 * @param {number} id
 * @param {ComparisonView} data
 * @param {string[]} pair
 */
function exportCard(kind, id, data, pair) {
  const format = h("select", { id: "export-format", "aria-label": "Export format" }, EXPORT_FORMATS.map(([v, l]) => h("option", { value: v }, l)));
  const method = h("select", { id: "export-method", "aria-label": "Method to export" },
    data.planned.map((m) => h("option", { value: m, selected: m === pair[1] }, methodInfo(m).label)));
  const rate = h("input", { id: "export-rate", type: "number", min: "1", max: "10000", step: "any", placeholder: "format's default", "aria-label": "Sample rate [Hz]", style: "width:140px" });
  const status = h("span", { class: "small muted", id: "export-status", role: "status" });
  const button = h("button", { type: "button", class: "primary", id: "export-download" }, "Download trajectory");
  button.addEventListener("click", () => {
    const url = `/api/${kind === "simulation" ? "simulations" : "plans"}/${id}/trajectory${qs({ format: format.value, method: method.value, rate: rate.value })}`;
    download(url, button, status);
  });
  const fileStatus = h("span", { class: "small muted", id: "report-status", role: "status" });
  /** @param {string} fmtName @param {string} text */
  const fileButton = (fmtName, text) => {
    const b = h("button", { type: "button", id: `export-${fmtName}` }, text);
    b.addEventListener("click", () => download(data.exports[fmtName], b, fileStatus));
    return b;
  };
  return h("section", { class: "card", id: "export-card" },
    h("h2", {}, "Export"),
    h("div", { class: "row", style: "flex-wrap:wrap; gap:8px" },
      h("label", { class: "small" }, "format ", format), h("label", { class: "small" }, "method ", method),
      h("label", { class: "small" }, "rate [Hz] ", rate), button, status),
    h("div", { class: "row", style: "flex-wrap:wrap; gap:8px; margin-top:10px" },
      fileButton("scene", "3-D scene (HTML)"), fileButton("report", "Report (HTML)"), fileStatus),
    h("p", { class: "small muted" }, "Trajectories in the formats robot controllers read (docs/export.md); the scene and report open without the server."),
  );
}

/**
 * The methods a sweep's cells compared with the quintic (the paper's first).
 * @param {import("./types").SweepResult} r
 * @returns {string[]}
 */
function sweepMethods(r) {
  const found = new Set();
  for (const c of r.cells) Object.keys(c.methods_change_pct || {}).forEach((m) => found.add(m));
  found.delete("quintic");
  return ["paper", ...[...found].filter((m) => m !== "paper")];
}

/**
 * (durations x payloads) change [%] of `method` in `metric` (null where a cell is not ok).
 * @param {import("./types").SweepResult} r
 * @param {string} objective
 * @param {string} metric
 * @param {string} method
 * @returns {(number | null)[][]}
 */
function sweepGrid(r, objective, metric, method) {
  return r.durations.map((d) => r.payloads.map((p) => {
    const c = r.cells.find((x) => x.duration === d && x.payload === p && x.objective === objective);
    const v = c && c.status === "ok" ? (c.methods_change_pct || {})[method]?.[metric] : null;
    return typeof v === "number" ? v : null;
  }));
}

/** @param {import("./types").SweepOut} sweep a succeeded sweep */
function sweepCard(sweep) {
  const r = /** @type {import("./types").SweepResult} */ (sweep.result);
  const objectives = r.objectives;
  const metrics = r.metrics;
  const methods = sweepMethods(r);
  let objective = objectives[0];
  // The metric the sweep optimised first: what its heat map is about.
  let metric = metrics.includes(objective) ? objective : metrics.includes("abs_work") ? "abs_work" : metrics[0];
  let method = "paper";
  const div = h("div", { class: "plot", id: "sweep-plot", style: "min-height:360px" });
  const selObj = h("select", { "aria-label": "Sweep objective" }, objectives.map((o) => h("option", { value: o }, `objective ${o}`)));
  const selMet = h("select", { "aria-label": "Sweep metric" }, metrics.map((m) => h("option", { value: m, selected: m === metric }, `metric ${m}`)));
  const selMethod = h("select", { "aria-label": "Sweep method", id: "sweep-method" }, methods.map((m) => h("option", { value: m }, methodInfo(m).label)));
  const redraw = () => {
    const table = r.tables[objective][metric];
    // The paper's method: the stored table with each cell's checked verdict; the others: their
    // change per cell.
    const z = method === "paper" ? table.change_pct : sweepGrid(r, objective, metric, method);
    /** @param {number} i @param {number} k */
    const verdict = (i, k) => (method === "paper" ? `<br>${table.classification[i][k]}` : "");
    const text = z.map((row, i) => row.map((v, k) => `${v === null ? "–" : `${v > 0 ? "+" : ""}${v.toFixed(1)} %`}${verdict(i, k)}`));
    const lim = Math.max(5, ...z.flat().filter((v) => v !== null).map((v) => Math.abs(v)));
    div.dataset.method = method;
    draw(div, [{
      type: "heatmap", z, x: r.payloads.map((p) => `${p} kg`), y: r.durations.map((d) => `${d} s`), text, texttemplate: "%{text}",
      hovertemplate: "T %{y}, m %{x}: %{z:.1f} %<extra></extra>", zmin: -lim, zmax: lim, zmid: 0,
      colorscale: [[0, "#cf222e"], [0.5, "#f6f8fa"], [1, "#1a7f37"]], colorbar: { title: { text: "change [%]" } },
    }], layout({ height: 360, hovermode: "closest", xaxis: { title: { text: "payload" } }, yaxis: { title: { text: "duration" } }, margin: { l: 70, r: 10, t: 20, b: 50 } }));
  };
  selObj.addEventListener("change", () => { objective = selObj.value; redraw(); });
  selMet.addEventListener("change", () => { metric = selMet.value; redraw(); });
  selMethod.addEventListener("change", () => { method = selMethod.value; redraw(); });
  const card = h("section", { class: "card", id: "sweep-card" },
    h("div", { class: "row" }, h("h2", { style: "margin:0" }, `Sweep #${sweep.id}: ${r.robot}`), h("span", { class: "small muted" }, when(sweep.job.finished_at)),
      h("span", { class: "row", style: "margin-left:auto" }, selMethod, selObj, selMet)),
    h("p", { class: "small muted" }, "Where a method saves (green) and where it costs more (red) than the standard quintic: change in % of the quintic, 100 (quintic − method) / quintic, per duration and payload (simulated in MuJoCo). The paper's method's cells also give the verdict checked by a second PSO run."),
    div,
  );
  plotly().then(redraw);
  return card;
}
