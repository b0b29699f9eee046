// "Sweep a grid" on the Plan page: every method planned and simulated in each cell of a
// duration x payload grid (POST /api/sweeps, `bioplan sweep`), with progress per cell. The
// robot, objective, methods and swarm come from the plan form above; the heat maps per method
// are shown on the Compare page (#/compare?sweep=ID), beside a comparison of the same robot.

import { api, followJob } from "./api.js";
import { banner, clear, h, inFormWords, tag } from "./ui.js";

/** @typedef {import("./types").JobInfo} JobInfo */

/** The sweep request's fields in the words of the forms they come from. */
const SWEEP_WORDS = {
  durations: "Durations", payloads: "Payloads", objectives: "Objective", methods: "Methods",
  robot: "Robot", particles: "Particles", iterations: "Iterations", seed: "Seed",
};

/**
 * Numbers from "0.5, 1, 1.5" (commas or blanks); throws naming the field when one is not.
 * @param {string} text
 * @param {string} what the field's label
 * @returns {number[]}
 */
export function numberList(text, what) {
  const parts = text.split(/[\s,;]+/).filter(Boolean);
  const values = parts.map(Number);
  const bad = parts.find((_p, i) => !Number.isFinite(values[i]));
  if (bad !== undefined) throw new Error(`${what}: "${bad}" is not a number (give numbers separated by commas)`);
  if (!values.length) throw new Error(`${what}: give at least one value`);
  return values;
}

/**
 * A job's progress as the forms show it: its name and state, a bar, and one line per update
 * (the sweep's cells, a front's points). The pages' tests find the parts by `ids`.
 * @param {{ state: string, message: string }} job the job as submitted
 * @param {string} title e.g. "Sweep #3"
 * @param {{ progress: string, state: string, detail: string }} ids of the bar, the state tag and the line
 * @param {(job: JobInfo) => string} detail an update's line
 * @returns {{ element: HTMLElement, update: (job: JobInfo) => void, finish: (job: JobInfo) => HTMLElement | null }}
 *   `update` shows a job update; `finish` marks the bar done or failed and returns, for a job
 *   that did not succeed, the banner saying so
 */
export function jobProgress(job, title, ids, detail) {
  const bar = h("div", {});
  const prog = h("div", { class: "progress", id: ids.progress, role: "progressbar", "aria-valuemin": "0", "aria-valuemax": "100", "aria-valuenow": "0" }, bar);
  const state = h("span", { id: ids.state }, tag(job.state));
  const line = h("div", { class: "small muted", id: ids.detail }, job.message);
  /** @param {JobInfo} j */
  const update = (j) => {
    const p = Math.round(100 * j.progress);
    bar.style.width = `${p}%`;
    prog.setAttribute("aria-valuenow", String(p));
    clear(state).append(tag(j.state));
    line.textContent = detail(j);
  };
  /** @param {JobInfo} final */
  const finish = (final) => {
    const ok = final.state === "succeeded";
    prog.classList.add(ok ? "done" : "failed");
    if (ok) return null;
    return banner(final.state === "cancelled" ? "warn" : "error", final.state === "cancelled" ? "Cancelled." : `Failed: ${final.error}`);
  };
  const element = h("div", {}, h("div", { class: "row" }, h("strong", {}, title), state), prog, line);
  return { element, update, finish };
}

/**
 * The card. `form` reads the plan form's shared choices: () => ({robot, objective, methods,
 * particles, iterations, seed}). `stops` collects the page's cleanup functions.
 * @param {() => Record<string, unknown>} form
 * @param {(() => void)[]} stops
 * @returns {HTMLFormElement}
 */
export function sweepFormCard(form, stops) {
  const durations = h("input", { id: "sweep-durations", value: "0.5, 1, 1.5", "aria-describedby": "sweep-hint" });
  const payloads = h("input", { id: "sweep-payloads", value: "0, 4, 8" });
  const status = h("div", { id: "sweep-status" });
  const submit = h("button", { type: "submit", class: "primary", id: "submit-sweep" }, "Run the sweep");

  /** @param {JobInfo} job the submitted sweep */
  function follow(job) {
    const box = jobProgress(job, `Sweep #${job.id}`, { progress: "sweep-progress", state: "sweep-state", detail: "sweep-cells" },
      (j) => (j.stage === "sweep" ? `cell ${j.done} of ${j.of} done · ${j.message}` : j.error || j.message));
    clear(status).append(box.element);
    const watch = followJob(job, box.update);
    stops.push(watch.stop);
    watch.done.then(async (final) => {
      const failed = box.finish(final);
      if (failed) {
        status.append(failed);
        return;
      }
      // That sweep's heat maps, beside a comparison of its robot.
      status.append(h("a", { class: "button", id: "open-sweep", href: `#/compare?sweep=${final.id}` }, "Heat maps per method on Compare →"));
    });
  }

  /** @param {SubmitEvent} e */
  async function onSubmit(e) {
    e.preventDefault();
    clear(status);
    let body;
    try {
      body = { ...form(), durations: numberList(durations.value, "Durations"), payloads: numberList(payloads.value, "Payloads") };
    } catch (err) {
      status.append(banner("error", err.message));
      return;
    }
    submit.disabled = true;
    try {
      follow(await api("/api/sweeps", { method: "POST", body }));
    } catch (err) {
      status.append(banner("error", inFormWords(err, SWEEP_WORDS)));
    } finally {
      submit.disabled = false;
    }
  }

  return h("form", { class: "card", id: "sweep-form", novalidate: true, onsubmit: onSubmit },
    h("h2", {}, "Sweep a grid"),
    h("p", { class: "small muted", id: "sweep-hint" }, "Every checked method is planned and simulated in each cell of durations × payloads, with the robot, objective, methods and swarm chosen above; each cell's verdict is checked by a second PSO run. Heat maps per method appear on Compare beside a comparison of the same robot."),
    h("div", { class: "fields" },
      h("div", {}, h("label", { for: "sweep-durations" }, "Durations ", h("span", { class: "hint" }, "[s]")), durations),
      h("div", {}, h("label", { for: "sweep-payloads" }, "Payloads ", h("span", { class: "hint" }, "[kg]")), payloads)),
    h("div", { class: "row", style: "margin-top:12px" }, submit),
    status);
}
