// The job drawer on every page: running and recent jobs with progress, cancel and a link to the
// result, updated live from one Server-Sent Events stream (GET /api/events/jobs). It lives in
// the shell, not in a page, so it survives navigation; the server keeps the jobs, so a reload
// shows them again. Each job has a "Log" toggle: what its science said while it ran (GET
// /api/jobs/{id}/log: methods, solve times, channels, failures), read once it has ended.

import { api, qs } from "./api.js";
import { isTerminal } from "./names.js";
import { clear, fmt, h, messageOf, tag, when } from "./ui.js";

const OPEN_KEY = "bioplan.drawer.open";
const RECENT = 20;
/** Seconds between polls when the stream cannot be used (a proxy, reads needing a token). */
const POLL_SECONDS = 5;
/** Seconds before a refused job stream is tried again (polling meanwhile). */
const RETRY_STREAM_SECONDS = 60;

/** @type {Record<string, string>} */
const KIND_WORDS = { analysis: "Analysis", pose: "Video to pose", plan: "Plan", simulation: "Simulation", sweep: "Sweep", profiles: "Profiles", cohort: "Cohort", identify: "Identify robot", front: "Pareto front" };

/** @typedef {import("./types").JobSummary} JobSummary */

/**
 * Where a finished job's result is shown in the dashboard (null: nowhere).
 * @param {Pick<JobSummary, "kind" | "id" | "recording_id">} job
 * @returns {[string, string] | null} the address and the link's words
 */
export function resultLink(job) {
  if (job.kind === "plan" || job.kind === "simulation") return [`#/compare/${job.kind}/${job.id}`, "Compare"];
  if ((job.kind === "analysis" || job.kind === "pose") && job.recording_id) return [`#/recordings/${job.recording_id}`, "Recording"];
  if (job.kind === "sweep") return [`#/compare?sweep=${job.id}`, "Heat maps"];
  if (job.kind === "cohort") return [`#/cohort/${job.id}`, "Groups and tests"];
  if (job.kind === "identify") return ["#/validate", "Validate"];
  if (job.kind === "front") return [`#/compare/fronts/${job.id}`, "Trade-offs"];
  return null;
}

/**
 * A job's log as shown under it: the lines, or why there are none (yet).
 * @param {{id: number, state: string}} job
 * @param {string[] | string | undefined} log the lines, an error, or undefined while read
 */
function logView(job, log) {
  const text = !isTerminal(job.state) ? "The log arrives when the job ends."
    : log === undefined ? "Reading the log…"
      : typeof log === "string" ? `The log cannot be read: ${log}`
        : log.length ? log.join("\n") : "Nothing logged.";
  return h("pre", { class: "job-log small mono", dataset: { jobId: String(job.id) }, style: "max-height:16em; overflow:auto; white-space:pre-wrap; margin:2px 0" }, text);
}

/**
 * One job of the drawer.
 * @param {JobSummary} job
 * @param {(job: JobSummary, button: HTMLButtonElement) => void} onCancel
 * @param {{open: boolean, log: string[] | string | undefined, toggle: (job: JobSummary) => void}} log
 */
function jobItem(job, onCancel, log) {
  const active = !isTerminal(job.state);
  const pctDone = Math.round(100 * job.progress);
  const link = job.state === "succeeded" ? resultLink(job) : null;
  const detail = job.state === "failed" ? job.error : job.state === "succeeded" ? null : job.message;
  return h("li", { class: `job-item ${job.state}`, dataset: { jobId: String(job.id), state: job.state } },
    h("div", { class: "row" },
      h("strong", {}, `${KIND_WORDS[job.kind] || job.kind} #${job.id}`),
      job.label ? h("span", { class: "job-label", title: "the job's label" }, `“${job.label}”`) : null, tag(job.state),
      h("span", { class: "small muted", style: "margin-left:auto" }, active ? (job.run_seconds === null ? "waiting" : `${fmt(job.run_seconds, 3)} s`) : when(job.finished_at))),
    h("div", { class: "small mono" }, job.about),
    active ? h("div", { class: "progress", role: "progressbar", "aria-valuemin": "0", "aria-valuemax": "100", "aria-valuenow": String(pctDone) },
      h("div", { style: `width:${pctDone}%` })) : null,
    detail ? h("div", { class: `small ${job.state === "failed" ? "error-text" : "muted"}` }, detail) : null,
    log.open ? logView(job, log.log) : null,
    h("div", { class: "row" },
      h("button", { type: "button", class: "small job-log-toggle", "aria-expanded": String(log.open), onclick: () => log.toggle(job) }, log.open ? "Hide log" : "Log"),
      link ? h("a", { class: "job-open", href: link[0] }, `${link[1]} →`) : null,
      // A running plan: its progress and convergence curve on the Plan page.
      active && (job.kind === "plan" || job.kind === "simulation") ? h("a", { class: "job-follow", href: `#/plan?job=${job.id}` }, "Progress →") : null,
      job.kind === "analysis" && job.state === "succeeded" ? h("a", { href: `#/plan?analysis=${job.id}` }, "Use template") : null,
      active ? h("button", { type: "button", class: "danger small job-cancel", style: "margin-left:auto", onclick: (/** @type {MouseEvent} */ e) => onCancel(job, /** @type {HTMLButtonElement} */ (e.currentTarget)) }, "Cancel") : null));
}

/**
 * Mount the drawer: the header button toggles it; returns nothing (it lives as long as the page).
 * @param {HTMLElement} button the header's button, holding the #jobs-count badge
 * @param {HTMLElement} drawer
 */
export function mountJobDrawer(button, drawer) {
  /** @type {Map<number, JobSummary>} */
  const jobs = new Map(); // id -> JobSummary
  /** @type {Set<number>} */
  const openLogs = new Set(); // ids whose log is shown
  /** @type {Map<number, string[] | string>} an ended job's log lines, or why they cannot be read */
  const logs = new Map();
  const list = h("ul", { class: "job-list", id: "job-list" });
  const note = h("div", { id: "job-drawer-note", class: "small muted" });
  const count = /** @type {HTMLElement} */ (button.querySelector("#jobs-count"));
  clear(drawer).append(
    h("div", { class: "row" }, h("h2", { style: "margin:0" }, "Jobs"),
      h("button", { type: "button", class: "small", id: "job-drawer-close", style: "margin-left:auto", onclick: () => setOpen(false) }, "Close")),
    note, list);

  /** @param {boolean} open */
  function setOpen(open) {
    drawer.hidden = !open;
    button.setAttribute("aria-expanded", String(open));
    localStorage.setItem(OPEN_KEY, open ? "1" : "0");
  }
  button.addEventListener("click", () => setOpen(drawer.hidden));
  // Escape closes it (focus back on the button that opens it).
  document.addEventListener("keydown", (e) => {
    if (e.key !== "Escape" || drawer.hidden) return;
    setOpen(false);
    button.focus();
  });
  setOpen(localStorage.getItem(OPEN_KEY) === "1");

  /**
   * @param {JobSummary} job
   * @param {HTMLButtonElement} btn
   */
  async function cancel(job, btn) {
    btn.disabled = true;
    try {
      upsert(await api(`/api/jobs/${job.id}/cancel`, { method: "POST" }));
    } catch (err) {
      note.textContent = `Job #${job.id} could not be cancelled: ${messageOf(err)}`;
      btn.disabled = false;
    }
  }

  /** @type {Set<number>} */
  const reading = new Set(); // ids whose log is being read

  /**
   * Read an ended job's log once (it does not change any more), then show it.
   * @param {JobSummary} job
   */
  async function readLog(job) {
    reading.add(job.id);
    try {
      const body = await api(`/api/jobs/${job.id}/log`);
      logs.set(job.id, body.complete ? body.lines : `job #${job.id} has not ended yet`);
    } catch (err) {
      logs.set(job.id, messageOf(err));
    }
    reading.delete(job.id);
    render();
  }

  /** @param {JobSummary} job */
  function toggleLog(job) {
    if (openLogs.has(job.id)) openLogs.delete(job.id);
    else openLogs.add(job.id);
    if (typeof logs.get(job.id) === "string") logs.delete(job.id); // a failed read: try again
    render();
  }

  function render() {
    const sorted = [...jobs.values()].sort((a, b) => b.id - a.id);
    const running = sorted.filter((j) => !isTerminal(j.state));
    // Every active job, then the newest finished ones.
    const shown = running.concat(sorted.filter((j) => isTerminal(j.state)).slice(0, RECENT));
    for (const j of shown) {
      // A shown log of a job that just ended: read it now.
      if (openLogs.has(j.id) && isTerminal(j.state) && !logs.has(j.id) && !reading.has(j.id)) readLog(j);
    }
    clear(list).append(...shown.map((j) => jobItem(j, cancel, { open: openLogs.has(j.id), log: logs.get(j.id), toggle: toggleLog })));
    if (!shown.length) list.append(h("li", { class: "muted small" }, "No jobs yet: analyses, plans, simulations and sweeps appear here while they run."));
    if (String(running.length) !== (count.textContent || "0")) {
      // The header's status line says how many run: it reads them again at once.
      document.dispatchEvent(new CustomEvent("bioplan:jobs", { detail: { active: running.length } }));
    }
    count.textContent = running.length ? String(running.length) : "";
    count.hidden = !running.length;
    button.title = running.length ? `${running.length} job(s) running` : "No job running";
  }

  /** @param {JobSummary & { params?: Record<string, any> }} job a summary, or a full Job */
  function upsert(job) {
    const { params, ...rest } = job; // a full Job from a cancel: the drawer keeps the summary form
    const old = jobs.get(job.id);
    jobs.set(job.id, { ...old, ...rest, about: rest.about ?? old?.about ?? "", label: rest.label ?? old?.label ?? null, recording_id: rest.recording_id ?? old?.recording_id ?? params?.recording_id ?? null });
    render();
  }

  /** @type {ReturnType<typeof setInterval> | null} */
  let poll = null;
  async function pollOnce() {
    try {
      /** @type {import("./types").Page<import("./types").JobInfo & { params: Record<string, any> }>} */
      const page = await api(`/api/jobs${qs({ limit: RECENT })}`);
      for (const j of page.items) upsert({ ...j, about: j.params.robot || (j.params.recording_id ? `recording #${j.params.recording_id}` : "") });
    } catch (err) {
      note.textContent = `Jobs cannot be read: ${messageOf(err)}`;
    }
  }

  function connect() {
    const source = new EventSource(`/api/events/jobs${qs({ recent: RECENT })}`);
    source.addEventListener("jobs", (e) => {
      jobs.clear();
      for (const j of JSON.parse(e.data)) jobs.set(j.id, j);
      note.textContent = "";
      if (poll) clearInterval(poll);
      poll = null;
      render();
    });
    source.addEventListener("job", (e) => upsert(JSON.parse(e.data)));
    source.onerror = () => {
      // The browser reconnects by itself when the stream ends (the server ends an idle one
      // after BIOPLAN_STREAM_IDLE_S) unless the server refused it (429: too many streams):
      // then poll, and try the stream again a minute later.
      if (source.readyState === EventSource.CLOSED) {
        if (!poll) {
          note.textContent = "Live updates are unavailable; refreshed every few seconds.";
          pollOnce();
          poll = setInterval(pollOnce, POLL_SECONDS * 1000);
        }
        setTimeout(connect, RETRY_STREAM_SECONDS * 1000);
      }
    };
  }
  render();
  connect();
}
