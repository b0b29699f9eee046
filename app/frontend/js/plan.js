// Plan: robot, task, duration, payload, objective, template, PSO settings; submit; live
// progress (Server-Sent Events) and the convergence curve as it grows; cancel.

import { api, followJob, qs } from "./api.js";
import { names } from "./names.js";
import { colours, draw, layout } from "./plots.js";
import { robotUploadCard } from "./robot_upload.js";
import { sweepFormCard } from "./sweep_form.js";
import { DEG, banner, clear, clearFieldErrors, fmt, h, messageOf, pct, showCaps, showFormErrors, tag } from "./ui.js";

/** @typedef {import("./types").RobotInfo} RobotInfo */

/**
 * The plan form's labels of the request's fields, for the server's messages.
 * @type {Record<string, string>}
 */
const PLAN_WORDS = {
  label: "Label", robot: "Robot", duration: "Duration", payload: "Payload", objective: "Objective",
  seed: "Seed", particles: "Particles", iterations: "Iterations", peak_angle_deg: "Elbow peak angle",
  template: "Template", template_analysis_id: "Template", methods: "Methods",
  human_constraint: "Human-like optimum's constraint", start_deg: "Start angles", goal_deg: "Goal angles",
  n_samples: "Samples", n_intervals: "Intervals", no_reversal: "No joint reversal",
};

/**
 * The optimisers' convergence from a job's structured progress: one curve per stage that
 * reports a best value (PSO iterations; optimal control), point `done` -> the best so far (a
 * running minimum: it never rises, whatever a stage reports between its iterations).
 * @param {Record<string, { x: number[], y: number[] }>} curves per stage, extended in place
 * @param {Pick<import("./types").JobInfo, "best" | "stage" | "done">} job an update
 * @returns {boolean} whether a point was added
 */
export function addProgressPoint(curves, job) {
  if (job.best === null || job.best === undefined || !job.stage) return false;
  const curve = curves[job.stage] || (curves[job.stage] = { x: [], y: [] });
  if (curve.x.length && job.done <= /** @type {number} */ (curve.x.at(-1))) return false;
  curve.x.push(job.done);
  curve.y.push(curve.y.length ? Math.min(/** @type {number} */ (curve.y.at(-1)), job.best) : job.best);
  return true;
}

/** The form (and the job it followed) kept for this tab: leaving or reloading the page keeps them. */
const FORM_KEY = "bioplan.plan.form";
/** Methods planned only when asked for (DESIGN.md: the unrestricted bound): unchecked at first. */
const ON_REQUEST = new Set(["bound_unrestricted"]);
const JOB_KEY = "bioplan.plan.job";

/** @param {string} key */
function readStore(key) {
  try {
    return JSON.parse(sessionStorage.getItem(key) || "null");
  } catch {
    return null;
  }
}

/**
 * @param {string} key
 * @param {unknown} value stored as JSON
 */
function writeStore(key, value) {
  try {
    sessionStorage.setItem(key, JSON.stringify(value));
  } catch {
    /* storage full or off: the page still works, it only forgets */
  }
}

/**
 * A template's line in the list: its recording, angle and how many lifts it rests on.
 * @param {any} a a listed analysis (GET /api/analyses)
 * @param {string} of its recording, in words
 * @returns {string}
 */
function templateText(a, of) {
  const t = a.template || {};
  const summary = a.summary || {};
  const lifts = summary.n_lifts ?? t.n_lifts ?? 0;
  const peak = t.peak_velocity_angle_deg ? `${fmt(t.peak_velocity_angle_deg, 3)}°` : "?";
  const found = `${lifts} lift${lifts === 1 ? "" : "s"} found`;
  const rate = (summary.files || []).map((/** @type {any} */ f) => f.rate_check).find(Boolean);
  if (rate) return `analysis #${a.id} of ${of}: run at a wrong-looking EMG rate (${fmt(rate.stored_rate_hz)} Hz stored, ${fmt(rate.suggested_rate_hz)} Hz likely): ${found}, not a template of this person`;
  if (!lifts) return `analysis #${a.id} of ${of}: no lift found, so only the paper's default ${peak}`;
  const source = summary.is_paper_default ? "none with kinematics: the paper's default" : summary.template_source || `${t.n_lifts} with kinematics`;
  return `analysis #${a.id} of ${of}: peak ${peak}, ${found}, ${source}`;
}

/**
 * @param {HTMLElement} main
 * @param {Array<string | undefined>} match the query string, if any
 */
export async function render(main, [query]) {
  const params = new URLSearchParams(query || "");
  /** @type {(() => void)[]} */
  const stops = [];
  /** @type {[RobotInfo[], import("./types").Page<any>, import("./types").Page<any>]} */
  const [robots, analyses, recordings] = await Promise.all([
    api("/api/robots"),
    api(`/api/analyses${qs({ state: "succeeded", limit: 100 })}`).catch(() => ({ items: [] })),
    api(`/api/recordings${qs({ limit: 500 })}`).catch(() => ({ items: [] })),
  ]);
  // Templates are named by their recording's label, subject and task, not only by ids.
  const recordingNames = new Map(recordings.items.map((r) => {
    const who = [r.subject, r.task].filter(Boolean).join(", ");
    return [r.id, r.label ? `“${r.label}”${who ? ` (${who})` : ""}` : who || `recording #${r.id}`];
  }));

  // ---- form --------------------------------------------------------------------------
  /** @param {RobotInfo} r */
  const robotOption = (r) => h("option", { value: r.name, selected: params.get("robot") === r.name }, `${r.name}${r.builtin ? "" : r.identified_from ? ` (identified from ${r.identified_from.robot})` : " (uploaded)"}`);
  const robot = h("select", { id: "robot" }, robots.map(robotOption));
  const kind = h("select", { id: "kind" },
    h("option", { value: "simulation" }, "plan + MuJoCo simulation"),
    h("option", { value: "plan" }, "plan only"),
  );
  const duration = h("input", { id: "duration", type: "number", min: "0.05", max: "600", step: "0.05", value: "1.0", required: true });
  const payload = h("input", { id: "payload", type: "number", min: "0", max: "10000", step: "0.1" });
  const objective = h("select", { id: "objective" }, names.metrics.map((m) => h("option", { value: m.name }, `${m.name}: ${m.label} ${m.formula} [${m.unit}]`)));
  // An analysis that found no lift, or ran at an EMG rate that looked wrong, is no template of
  // this person: not offered, unless a link asks for it (then it says what it is).
  /** @param {any} a a listed analysis */
  const usable = (a) => {
    const summary = a.summary || {};
    const lifts = summary.n_lifts ?? (a.template || {}).n_lifts ?? 0;
    return lifts > 0 && !(summary.files || []).some((/** @type {any} */ f) => f.rate_check);
  };
  const offered = analyses.items.filter((a) => usable(a) || params.get("analysis") === String(a.id));
  const hiddenCount = analyses.items.length - offered.length;
  const template = h("select", { id: "template" },
    h("option", { value: "" }, "paper defaults (velocity peak in the middle of phase B)"),
    offered.map((a) => {
      const of = a.recording_id === null ? "a deleted recording" : recordingNames.get(a.recording_id) || `recording #${a.recording_id}`;
      return h("option", { value: String(a.id), selected: params.get("analysis") === String(a.id), dataset: { lifts: String((a.summary || {}).n_lifts ?? 0) } }, templateText(a, of));
    }),
  );
  const templateNote = hiddenCount
    ? h("div", { class: "small muted", id: "template-hidden" }, `${hiddenCount} analys${hiddenCount === 1 ? "is" : "es"} that found no lift or ran at a wrong-looking EMG rate ${hiddenCount === 1 ? "is" : "are"} not offered.`)
    : null;
  const methodBoxes = names.methods.map((m) => h("label", { class: "check", title: m.description },
    h("input", { type: "checkbox", value: m.name, checked: !ON_REQUEST.has(m.name), disabled: m.name === "quintic", dataset: { method: m.name } }),
    h("span", { class: "swatch", style: `background:${m.colour}` }), m.label));
  const humanConstraint = h("select", { id: "human-constraint" },
    names.human_constraints.map((c) => h("option", { value: c.name }, `${c.name}: ${c.description}`)));
  const peak = h("input", { id: "peak-angle", type: "number", min: "1", max: "179", step: "0.5", placeholder: "from the template" });
  const pso = names.pso_defaults;
  const particles = h("input", { id: "particles", type: "number", min: "2", max: "1000", step: "1", value: String(pso.particles) });
  const iterations = h("input", { id: "iterations", type: "number", min: "1", max: "10000", step: "1", value: String(pso.iterations) });
  const seed = h("input", { id: "seed", type: "number", min: "0", step: "1", value: String(pso.seed) });
  const label = h("input", { id: "plan-label", maxlength: "200", placeholder: "e.g. slow, heavy payload" });
  const jointsBody = h("tbody", {});
  const robotInfo = h("div", { class: "small muted", id: "robot-info" });

  function showRobot() {
    const r = /** @type {RobotInfo} */ (robots.find((x) => x.name === robot.value));
    payload.placeholder = r && r.payload !== null ? `default ${r.payload} kg` : "robot default";
    clear(jointsBody);
    r.joint_names.forEach((name, i) => {
      /** @param {number | null} v [rad] */
      const lim = (v) => (v === null ? "∞" : fmt(v * DEG, 3));
      jointsBody.append(h("tr", {},
        h("td", { class: "mono" }, name),
        h("td", { class: "small muted nowrap" }, `${lim(r.q_min[i])} … ${lim(r.q_max[i])}`),
        h("td", {}, h("input", { type: "number", step: "1", placeholder: "default", "aria-label": `${name} start [deg]`, dataset: { joint: String(i), end: "start" } })),
        h("td", {}, h("input", { type: "number", step: "1", placeholder: "default", "aria-label": `${name} goal [deg]`, dataset: { joint: String(i), end: "goal" } })),
      ));
    });
    clear(robotInfo).append(`${r.joint_names.length} joints${r.has_mjcf ? ", MJCF for simulation" : ", no MJCF: plan only"}`);
    kind.value = r.has_mjcf ? kind.value : "plan";
    kind.options[0].disabled = !r.has_mjcf;
  }
  robot.addEventListener("change", showRobot);
  showRobot();

  /** @param {"start" | "goal"} end */
  function angles(end) {
    const inputs = [.../** @type {NodeListOf<HTMLInputElement>} */ (jointsBody.querySelectorAll(`input[data-end="${end}"]`))];
    if (inputs.every((x) => x.value.trim() === "")) return null;
    // A partly filled task takes the curl task's value for the rest (as the API does).
    return inputs.map((x) => (x.value.trim() === "" ? null : Number(x.value)));
  }

  function body() {
    /** @param {HTMLInputElement} el */
    const num = (el) => (el.value.trim() === "" ? null : Number(el.value));
    /** @type {Record<string, any>} */
    const b = {
      label: label.value.trim() || null,
      robot: robot.value,
      duration: num(duration),
      payload: num(payload),
      objective: objective.value,
      seed: num(seed) ?? pso.seed,
      particles: num(particles) ?? pso.particles,
      iterations: num(iterations) ?? pso.iterations,
      peak_angle_deg: num(peak),
      template_analysis_id: template.value ? Number(template.value) : null,
      methods: methodBoxes.map((l) => /** @type {HTMLInputElement} */ (l.querySelector("input"))).filter((x) => x.checked).map((x) => x.value),
      human_constraint: humanConstraint.value,
      start_deg: angles("start"),
      goal_deg: angles("goal"),
    };
    for (const k of ["start_deg", "goal_deg"]) {
      if (b[k] && b[k].some((/** @type {number | null} */ v) => v === null)) throw new Error(`${k === "start_deg" ? "Start" : "Goal"} angles: give every joint or none (empty = the default curl task)`);
    }
    for (const k of Object.keys(b)) if (b[k] === null) delete b[k];
    return b;
  }

  const submit = h("button", { class: "primary", type: "submit", id: "submit-plan" }, "Plan");
  const formError = h("div", {});
  // Refusals beside their fields, and each field's cap as this server enforces it (issue 29).
  const capped = { duration, payload, particles, iterations, seed, peak_angle_deg: peak };
  showCaps("plan", { duration, payload, particles, iterations, peak_angle_deg: peak });
  const form = h("form", { class: "card", id: "plan-form", novalidate: true, onsubmit: onSubmit },
    h("h2", {}, "New plan"),
    formError, // at the top, where it is seen, in the form's words
    h("div", { class: "fields" },
      h("div", {}, h("label", { for: "robot" }, "Robot"), robot, robotInfo),
      h("div", {}, h("label", { for: "kind" }, "Run"), kind),
      h("div", {}, h("label", { for: "duration" }, "Duration ", h("span", { class: "hint" }, "[s]")), duration),
      h("div", {}, h("label", { for: "payload" }, "Payload ", h("span", { class: "hint" }, "[kg]")), payload),
      h("div", { class: "wide" }, h("label", { for: "objective" }, "Objective (what PSO minimises)"), objective),
      h("div", { class: "wide" }, h("label", { for: "template" }, "Human template"), template, templateNote),
      h("div", { class: "wide" }, h("label", { for: "peak-angle" }, "Elbow velocity-peak angle ", h("span", { class: "hint" }, "[deg], overrides the template")), peak),
    ),
    h("details", {},
      h("summary", {}, "Task: start and goal angles [deg]"),
      h("p", { class: "small muted" }, "Empty: the robot's curl task (shoulder 0→20°, elbow 0→150°)."),
      h("div", { class: "table-wrap" }, h("table", {}, h("thead", {}, h("tr", {}, h("th", {}, "joint"), h("th", {}, "limits [deg]"), h("th", {}, "start"), h("th", {}, "goal"))), jointsBody)),
    ),
    h("fieldset", { id: "methods-fieldset" },
      h("legend", {}, "Methods, side by side"),
      h("div", { class: "checks" }, methodBoxes),
      h("div", { class: "wide", style: "margin-top:8px" }, h("label", { for: "human-constraint" }, "Human-like optimum's constraint"), humanConstraint),
      h("p", { class: "small muted" }, "The standard quintic always runs: every saving is measured against it. The physical bound and the human-like optimum are solved by optimal control (CasADi + IPOPT)."),
    ),
    h("div", { class: "wide", style: "margin-top:12px" }, h("label", { for: "plan-label" }, "Label ", h("span", { class: "hint" }, "(optional: names it in every list)")), label),
    h("fieldset", {},
      h("legend", {}, "Particle swarm"),
      h("div", { class: "fields" },
        h("div", {}, h("label", { for: "particles" }, "Particles"), particles),
        h("div", {}, h("label", { for: "iterations" }, "Iterations (at most)"), iterations),
        h("div", {}, h("label", { for: "seed" }, "Seed"), seed),
      ),
    ),
    h("div", { class: "row", style: "margin-top:14px" }, submit),
  );

  // ---- job monitor -------------------------------------------------------------------
  const monitor = h("section", { class: "card", id: "job-card" },
    h("h2", {}, "Progress"),
    h("p", { class: "muted" }, "Submit a plan: its progress, the optimiser's convergence and the result appear here."),
  );
  /** Follow `job` here: its progress, the convergence curve (`curves` kept from before a
   * reload or a visit elsewhere, then grown from its events) and its result.
   * @param {import("./types").JobInfo & { params: Record<string, any> }} job
   * @param {Record<string, { x: number[], y: number[] }> | null} [kept]
   */
  function startMonitor(job, kept = null) {
    writeStore(JOB_KEY, { id: job.id, curves: kept || {} });
    const bar = h("div", {});
    const prog = h("div", { class: "progress", id: "job-progress", role: "progressbar", "aria-valuemin": "0", "aria-valuemax": "100", "aria-valuenow": "0" }, bar);
    const state = h("span", { id: "job-state" }, tag(job.state));
    const message = h("span", { class: "small muted", id: "job-message" }, job.message);
    const cancel = h("button", { type: "button", class: "danger small", id: "cancel-job" }, "Cancel");
    const plotDiv = h("div", { class: "plot", id: "convergence-plot", style: "min-height:240px" });
    const result = h("div", { id: "job-result" });
    clear(monitor).append(
      h("div", { class: "row" }, h("h2", { style: "margin:0" }, `${job.kind === "simulation" ? "Simulation" : "Plan"} #${job.id}`), state, h("span", { style: "margin-left:auto" }, cancel)),
      prog, message, plotDiv, result,
    );
    /** @type {Record<string, { x: number[], y: number[] }>} */
    let curves = kept || {};
    const objectiveName = job.params.objective;
    const drawCurve = () => {
      const stages = Object.keys(curves);
      // New arrays every time: Plotly.react redraws only data it sees change.
      const traces = stages.map((stage, i) => ({ x: [...curves[stage].x], y: [...curves[stage].y], mode: "lines+markers", line: { color: i ? colours().standard : colours().optimized, width: 2 }, marker: { size: 4 }, name: stage }));
      const xTitle = stages.length === 1 && stages[0] === "pso" ? "PSO iteration" : "iteration";
      return draw(plotDiv, traces, layout({ height: 240, showlegend: stages.length > 1, xaxis: { title: { text: xTitle }, gridcolor: "#eceff3" }, yaxis: { title: { text: `best ${objectiveName} so far` }, gridcolor: "#eceff3" }, datarevision: Date.now() }));
    };
    drawCurve();
    cancel.addEventListener("click", async () => {
      cancel.disabled = true;
      try {
        await api(`/api/jobs/${job.id}/cancel`, { method: "POST" });
      } catch (err) {
        result.append(banner("error", messageOf(err)));
      }
    });
    const follow = followJob(job, (j) => {
      const p = Math.round(100 * j.progress);
      bar.style.width = `${p}%`;
      prog.setAttribute("aria-valuenow", String(p));
      prog.dataset.stage = j.stage;
      clear(state).append(tag(j.state));
      message.textContent = j.error || j.message;
      if (addProgressPoint(curves, j)) {
        drawCurve();
        writeStore(JOB_KEY, { id: job.id, curves });
      }
    });
    stops.push(follow.stop);
    follow.done.then(async (final) => {
      cancel.hidden = true;
      if (final.state === "succeeded") {
        prog.classList.add("done");
        /** @type {import("./types").PlanOut} */
        const out = await api(final.result_url);
        // A succeeded plan or simulation has its result.
        const r = /** @type {import("./types").PlanResult} */ (out.result);
        const hist = r.optimizer && r.optimizer.history;
        if (hist && hist.length) {
          curves = { pso: { x: hist.map((_, i) => i + 1), y: hist } };
          drawCurve();
        }
        const imp = r.improvement_pct || {};
        /** @param {string} k */
        const change = (k) => (typeof imp[k] === "number" ? /** @type {number} */ (imp[k]) : null);
        // The energy metrics: those with a physical floor (names.metrics, from /api/meta).
        const shown = names.metrics.filter((m) => m.floor !== null && !m.per_joint).map((m) => m.name);
        clear(result).append(
          h("div", { class: "facts" },
            ...shown.map((k) => {
              const c = change(k);
              return h("div", { class: "fact" }, h("div", { class: "k" }, `${k} change`), h("div", { class: `v ${c === null ? "" : c > 0 ? "better" : c < 0 ? "worse" : ""}` }, pct(c)));
            }),
          ),
          h("p", { class: "small muted" }, "Change = 100 (standard − optimised) / standard: positive means the bio-inspired plan uses less."),
          h("a", { class: "button primary", id: "open-compare", href: `#/compare/${final.kind}/${final.id}` }, "Open in Compare →"),
        );
      } else {
        prog.classList.add("failed");
        result.append(banner(final.state === "cancelled" ? "warn" : "error", final.state === "cancelled" ? "Cancelled." : `Failed: ${final.error}`));
      }
    });
  }

  /** @param {SubmitEvent} e */
  async function onSubmit(e) {
    e.preventDefault();
    clear(formError);
    clearFieldErrors({ ...capped, label });
    let b;
    try {
      b = body();
    } catch (err) {
      formError.append(banner("error", err.message));
      formError.scrollIntoView({ block: "nearest" });
      return;
    }
    submit.disabled = true;
    try {
      const route = kind.value === "simulation" ? "/api/simulations" : "/api/plans";
      const job = await api(route, { method: "POST", body: b });
      startMonitor(job);
    } catch (err) {
      showFormErrors(formError, err, PLAN_WORDS, { ...capped, label });
    } finally {
      submit.disabled = false;
    }
  }

  const addRobot = robotUploadCard((r) => {
    robots.push(r);
    robot.append(robotOption(r));
    robot.value = r.name;
    showRobot();
  });
  const sweep = sweepFormCard(() => {
    const b = body();
    return { robot: b.robot, objectives: [b.objective], methods: b.methods, particles: b.particles, iterations: b.iterations, seed: b.seed };
  }, stops);
  main.append(h("div", { class: "grid-2" }, h("div", {}, form, addRobot), h("div", {}, monitor, sweep)));
  restoreForm();
  form.addEventListener("input", saveForm);
  form.addEventListener("change", saveForm);
  await reattach();
  return () => stops.forEach((f) => f());

  /** The form's values, the methods chosen and the task's angles, for this tab. */
  function saveForm() {
    /** @type {Record<string, string>} */
    const values = {};
    for (const el of /** @type {NodeListOf<HTMLInputElement | HTMLSelectElement>} */ (form.querySelectorAll("input[id], select[id]"))) values[el.id] = el.value;
    const methods = methodBoxes.map((l) => /** @type {HTMLInputElement} */ (l.querySelector("input"))).filter((x) => x.checked).map((x) => x.value);
    const joints = [...jointsBody.querySelectorAll("input")].map((x) => x.value);
    writeStore(FORM_KEY, { values, methods, joints });
  }

  /** The form as it was left (a link's robot or template wins over the kept one). */
  function restoreForm() {
    const saved = readStore(FORM_KEY);
    if (!saved || !saved.values) return;
    const v = saved.values;
    if (!params.get("robot") && robots.some((r) => r.name === v.robot)) robot.value = v.robot;
    showRobot();
    for (const [key, value] of Object.entries(v)) {
      if (key === "robot" || (key === "template" && params.get("analysis"))) continue;
      const el = /** @type {HTMLInputElement | HTMLSelectElement | null} */ (form.querySelector(`#${CSS.escape(key)}`));
      if (!el || (el.tagName === "SELECT" && ![.../** @type {HTMLSelectElement} */ (el).options].some((o) => o.value === value && !o.disabled))) continue;
      el.value = value;
    }
    const boxes = methodBoxes.map((l) => /** @type {HTMLInputElement} */ (l.querySelector("input")));
    if (Array.isArray(saved.methods)) boxes.forEach((x) => (x.checked = x.disabled || saved.methods.includes(x.value)));
    const inputs = [...jointsBody.querySelectorAll("input")];
    if (Array.isArray(saved.joints) && saved.joints.length === inputs.length && robot.value === v.robot) {
      inputs.forEach((x, i) => (x.value = saved.joints[i]));
    }
  }

  /** The plan this tab followed (or ?job=ID): its progress panel again, with its curve. */
  async function reattach() {
    const kept = readStore(JOB_KEY);
    const wanted = Number(params.get("job")) || (kept && kept.id);
    if (!wanted) return;
    try {
      const job = await api(`/api/jobs/${wanted}`);
      if (job.kind !== "plan" && job.kind !== "simulation") return;
      startMonitor(job, kept && kept.id === job.id ? kept.curves : null);
    } catch {
      if (kept && kept.id === wanted) sessionStorage.removeItem(JOB_KEY); // deleted meanwhile
    }
  }
}
