// Validate: upload a robot log for a robot, see measured against predicted torque per joint,
// the residuals, the energy comparison and (with a plan) the tracking; identify the robot from
// its logs as a background job, which stores a new robot version selectable on the Plan page.
// Routes: #/validate (upload and the robot's logs), #/validate/ID (one log's validation).

import { api, followJob, qs, upload } from "./api.js";
import { draw, layout } from "./plots.js";
import { banner, clear, fmt, h, inFormWords, messageOf, pct, when } from "./ui.js";

/** @typedef {import("./types").RobotInfo} RobotInfo */
/**
 * A stored robot log (GET /api/robot-logs, the fields this page reads).
 * @typedef {{ id: number, robot: string, file: string, label: string | null, format: string, samples: number,
 *   duration_s: number, rate_hz: number, created_at: string, joint_names: string[], notes: string[] }} RobotLog
 */

/** @type {Record<string, string>} */
const FIELD_WORDS = { robot: "Robot", file: "Log file", topic: "Topic", label: "Label", log_ids: "Logs", version: "Version name", plan: "Plan" };

/** @param {HTMLElement} main @param {Array<string|undefined>} match */
export async function render(main, match) {
  const id = match && match[0] ? Number(match[0]) : null;
  /** @type {(() => void)[]} */
  const stops = [];
  if (id) await renderLog(main, id, stops);
  else await renderUpload(main);
  return () => stops.forEach((stop) => stop());
}

/** @param {HTMLElement} main */
async function renderUpload(main) {
  /** @type {RobotInfo[]} */
  const robots = await api("/api/robots");
  const robot = h("select", { id: "log-robot" }, robots.map((r) => h("option", { value: r.name }, robotLabel(r))));
  const file = h("input", { type: "file", id: "log-file", accept: ".csv,.txt,.tsv,.zip" });
  const topic = h("input", { id: "log-topic", maxlength: "200", placeholder: "a bag's JointState topic (optional)" });
  const label = h("input", { id: "log-label", maxlength: "200", placeholder: "optional" });
  const error = h("div", { id: "log-error" });
  const submit = h("button", { type: "submit", class: "primary", id: "log-submit" }, "Upload and validate");
  const list = h("div", { id: "log-list" });

  async function showLogs() {
    /** @type {RobotLog[]} */
    const logs = await api(`/api/robot-logs${qs({ robot: robot.value })}`);
    clear(list).append(logs.length
      ? h("ul", {}, logs.map((l) => h("li", { dataset: { id: String(l.id) } },
        h("a", { href: `#/validate/${l.id}` }, `${l.file}`), l.label ? ` “${l.label}”` : "",
        h("span", { class: "small muted" }, ` ${fmt(l.duration_s)} s at ${fmt(l.rate_hz)} Hz, ${when(l.created_at)}`))))
      : h("p", { class: "muted" }, "No logs of this robot yet."));
  }

  /** @param {SubmitEvent} e */
  async function onSubmit(e) {
    e.preventDefault();
    clear(error);
    if (!file.files || !file.files.length) {
      error.append(banner("error", "Log file: choose a robot log (CSV, UR RTDE CSV, or a zipped ROS 2 bag)."));
      return;
    }
    const form = new FormData();
    form.append("robot", robot.value);
    form.append("file", file.files[0]);
    if (topic.value.trim()) form.append("topic", topic.value.trim());
    if (label.value.trim()) form.append("label", label.value.trim());
    submit.disabled = true;
    try {
      const log = await upload("/api/robot-logs", form);
      location.hash = `#/validate/${log.id}`;
    } catch (err) {
      error.append(banner("error", inFormWords(err, FIELD_WORDS)));
    } finally {
      submit.disabled = false;
    }
  }

  robot.addEventListener("change", () => showLogs().catch((err) => list.append(banner("error", messageOf(err)))));
  main.append(
    h("div", { class: "page-head" }, h("h1", {}, "Validate the robot model against a robot log")),
    h("p", { class: "muted" }, "A log of the real arm (joint positions, speeds, torques) shows how far the model's predicted torques and work are from what the robot measured; identifying the robot from its logs stores a better model as a new robot version."),
    h("form", { class: "card", id: "log-form", onsubmit: onSubmit, novalidate: true },
      h("div", { class: "fields" },
        h("div", {}, h("label", { for: "log-robot" }, "Robot"), robot),
        h("div", {}, h("label", { for: "log-file" }, "Log file"), file,
          h("div", { class: "small muted" }, "CSV: time, <joint>/position [rad], <joint>/velocity [rad/s] (optional), <joint>/effort [Nm]; a UR RTDE CSV; or a ROS 2 bag folder as a zip.")),
        h("div", {}, h("label", { for: "log-topic" }, "Topic"), topic),
        h("div", {}, h("label", { for: "log-label" }, "Label"), label)),
      error,
      h("div", { class: "row" }, submit)),
    h("section", { class: "card" }, h("h2", {}, "Logs of this robot"), list));
  await showLogs();
}

/** @param {RobotInfo} r */
function robotLabel(r) {
  if (r.builtin) return r.name;
  return r.identified_from ? `${r.name} (identified from ${r.identified_from.robot})` : `${r.name} (uploaded)`;
}

/**
 * @param {HTMLElement} main
 * @param {number} id the log's id
 * @param {(() => void)[]} stops the page's cleanup functions
 */
async function renderLog(main, id, stops) {
  /** @type {[RobotLog, RobotInfo[], import("./types").Page<import("./types").PlanOut>]} */
  const [log, robots, plans] = await Promise.all([
    api(`/api/robot-logs/${id}`),
    api("/api/robots"),
    api(`/api/plans${qs({ limit: 50, state: "succeeded" })}`).catch(() => ({ items: [] })),
  ]);
  const same = robots.filter((r) => sameJoints(r, log.joint_names));
  const robot = h("select", { id: "validate-robot" }, same.map((r) => h("option", { value: r.name, selected: r.name === log.robot }, robotLabel(r))));
  const plan = h("select", { id: "validate-plan" }, h("option", { value: "" }, "none"),
    (plans.items || []).filter((p) => same.some((r) => r.name === p.robot)).map((p) => h("option", { value: p.id }, `Plan #${p.id} (${p.robot})${p.label ? ` “${p.label}”` : ""}`)));
  const result = h("div", { id: "validate-result" });
  const error = h("div", { id: "validate-error" });

  async function show() {
    clear(error);
    clear(result).append(h("p", { class: "muted" }, "Computing…"));
    try {
      const out = await api(`/api/robot-logs/${id}/validation${qs({ robot: robot.value, plan: plan.value || null })}`);
      clear(result);
      await showValidation(result, out);
    } catch (err) {
      clear(result);
      error.append(banner("error", inFormWords(err, FIELD_WORDS)));
    }
  }
  robot.addEventListener("change", show);
  plan.addEventListener("change", show);

  main.append(
    h("div", { class: "page-head" }, h("div", {}, h("a", { href: "#/validate", class: "small" }, "← Logs"),
      h("h1", {}, `${log.file} on ${log.robot}`))),
    h("p", { class: "small muted", id: "log-summary" },
      `${log.format}, ${log.samples} samples, ${fmt(log.duration_s)} s at ${fmt(log.rate_hz)} Hz; joints ${log.joint_names.join(", ")}.`,
      log.notes.length ? ` Notes: ${log.notes.join("; ")}.` : ""),
    h("div", { class: "card row" },
      h("label", { for: "validate-robot", style: "margin:0" }, "Predict with"), robot,
      h("label", { for: "validate-plan", style: "margin:0" }, "Plan the log executed"), plan),
    error, result, identifyCard(log, stops, async (version) => {
      const r = await api(`/api/robots/${encodeURIComponent(version)}`);
      robots.push(r);
      robot.append(h("option", { value: r.name }, robotLabel(r)));
      robot.value = r.name;
      void show(); // the new version's residuals fill in below when computed
    }));
  await show();
}

/**
 * @param {RobotInfo} r
 * @param {string[]} names
 */
function sameJoints(r, names) {
  return names.every((n) => r.joint_names.includes(n));
}

/**
 * @param {HTMLElement} box
 * @param {any} out GET /api/robot-logs/{id}/validation (no response model yet)
 */
async function showValidation(box, out) {
  const names = Object.keys(out.joints);
  const work = out.abs_work;
  const off = work.measured ? (100 * (work.predicted - work.measured)) / work.measured : null;
  box.append(
    h("div", { class: "table-wrap" }, h("table", { id: "validate-joints" },
      h("thead", {}, h("tr", {}, h("th", {}, "Joint"), h("th", {}, "rms measured [Nm]"), h("th", {}, "rms residual [Nm]"), h("th", {}, "R²"))),
      h("tbody", {}, names.map((n) => h("tr", { dataset: { joint: n } }, h("td", {}, n),
        h("td", {}, fmt(out.joints[n].rms_measured)), h("td", { class: "residual" }, fmt(out.joints[n].residual_rms)), h("td", {}, fmt(out.joints[n].r2))))))),
    h("p", { id: "validate-energy" }, `Mechanical work |τ·q̇| over the log: measured ${fmt(work.measured)} J, predicted ${fmt(work.predicted)} J (${pct(off)}).`,
      out.electrical_energy ? ` Electrical energy: measured ${fmt(out.electrical_energy.measured)} J, predicted ${fmt(out.electrical_energy.predicted)} J.` : ""),
    h("p", { class: "small muted" }, `Filter: ${out.filter.kind}, cutoff ${fmt(out.filter.cutoff_hz)} Hz, delay ${fmt(out.filter.delay_s)} s; ${fmt(out.filter.trimmed_s)} s trimmed at each end.`));
  if (out.plan) box.append(trackingCard(out.plan));
  const plots = h("div", { class: "grid-plots", id: "validate-plots" });
  box.append(plots);
  const s = out.series;
  for (let j = 0; j < s.joints.length; j += 1) {
    const div = h("div", { class: "plot validate-torque", dataset: { joint: s.joints[j] } });
    plots.append(div);
    await draw(div, [
      { x: s.t, y: s.measured[j], name: "measured", mode: "lines", line: { color: "#374151" } },
      { x: s.t, y: s.predicted[j], name: "predicted", mode: "lines", line: { color: "#2563eb" } },
      { x: s.t, y: s.measured[j].map((/** @type {number} */ m, /** @type {number} */ k) => m - s.predicted[j][k]), name: "residual", mode: "lines", line: { color: "#dc2626", width: 1 } },
    ], layout({ title: { text: `${s.joints[j]} torque [Nm]`, font: { size: 13 } }, xaxis: { title: { text: "t [s]" } }, height: 280 }));
  }
  const power = h("div", { class: "plot", id: "validate-power" });
  plots.append(power);
  await draw(power, [
    { x: s.t, y: s.power_measured, name: "measured", mode: "lines", line: { color: "#374151" } },
    { x: s.t, y: s.power_predicted, name: "predicted", mode: "lines", line: { color: "#2563eb" } },
  ], layout({ title: { text: "Σ|τ·q̇| [W]", font: { size: 13 } }, xaxis: { title: { text: "t [s]" } }, height: 280 }));
}

/** @param {any} p the validation's `plan` part (tracking of a plan) */
function trackingCard(p) {
  const joints = Object.keys(p.tracking_error_rms_rad);
  const saving = p.saving_pct;
  return h("section", { class: "card", id: "validate-tracking" },
    h("h2", {}, `Tracking of the plan's ${p.method}`),
    h("p", {}, `The plan starts ${fmt(p.time_shift_s)} s into the log.`,
      saving ? ` Saving against the quintic: planned ${pct(saving.planned)}, measured ${pct(saving.measured)}.` : ""),
    h("table", {}, h("thead", {}, h("tr", {}, h("th", {}, "Joint"), h("th", {}, "rms error [rad]"), h("th", {}, "max error [rad]"))),
      h("tbody", {}, joints.map((n) => h("tr", {}, h("td", {}, n), h("td", {}, fmt(p.tracking_error_rms_rad[n])), h("td", {}, fmt(p.tracking_error_max_rad[n])))))));
}

/**
 * @param {RobotLog} log
 * @param {(() => void)[]} stops the page's cleanup functions
 * @param {(version: string) => Promise<void>} onVersion called with the stored robot version
 *   (resolves once it is offered and selected; its residuals follow)
 */
function identifyCard(log, stops, onVersion) {
  const version = h("input", { id: "identify-version", maxlength: "100", placeholder: `${log.robot}-identified` });
  const fraction = h("input", { id: "identify-fraction", type: "number", min: "0", max: "0.89", step: "0.05", value: "0.2" });
  const button = h("button", { type: "submit", class: "primary", id: "identify-submit" }, "Identify the robot from this log");
  const progress = h("div", { id: "identify-progress" });
  /** @param {SubmitEvent} e */
  async function onSubmit(e) {
    e.preventDefault();
    clear(progress);
    button.disabled = true;
    try {
      /** @type {{ log_ids: number[], validate_fraction: number, version?: string }} */
      const body = { log_ids: [log.id], validate_fraction: Number(fraction.value) };
      if (version.value.trim()) body.version = version.value.trim();
      const job = await api("/api/identifications", { method: "POST", body });
      const bar = h("div", {});
      const line = h("div", { class: "small muted", id: "identify-progress-text" }, "queued");
      progress.append(h("div", { class: "progress", role: "progressbar" }, bar), line);
      const follower = followJob(job, (j) => {
        bar.style.width = `${Math.round(100 * j.progress)}%`;
        line.textContent = j.state === "running" ? j.message : j.state;
      });
      stops.push(follower.stop);
      const final = await follower.done;
      if (final.state !== "succeeded") {
        progress.append(banner("error", final.error || `The identification ${final.state}.`));
        return;
      }
      /** @type {import("./api_types").IdentificationResultOut} */
      const out = await api(final.result_url);
      line.textContent = `Stored as robot ${out.version}: select it on the Plan page.`;
      await onVersion(out.version); // offered and selected here before the link says done
      progress.append(h("p", { id: "identify-done" }, h("a", { href: `#/plan?robot=${encodeURIComponent(out.version)}` }, `Plan with ${out.version} →`)));
    } catch (err) {
      progress.append(banner("error", inFormWords(err, FIELD_WORDS)));
    } finally {
      button.disabled = false;
    }
  }
  return h("form", { class: "card", id: "identify-form", onsubmit: onSubmit, novalidate: true },
    h("h2", {}, "Identify"),
    h("p", { class: "small muted" }, "Fits the links' inertial parameters, friction and torque offsets to this log (physically consistent, regularised towards the URDF) and stores the result as a new robot version beside the nominal one. Built-in robots take no sidecar: upload the robot's URDF to identify it."),
    h("div", { class: "fields" },
      h("div", {}, h("label", { for: "identify-version" }, "Version name"), version),
      h("div", {}, h("label", { for: "identify-fraction" }, "Held back for checking"), fraction)),
    h("div", { class: "row" }, button), progress);
}
