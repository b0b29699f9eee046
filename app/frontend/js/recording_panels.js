// Panels of the recording detail page that change what is analysed: the data checks (an
// implausible EMG rate with its one-click fix, the readers' warnings), the channels (muscle
// mapping and exclusions, rerun without uploading again), the analysis options (every option of
// POST /api/analyses), and the video frames with the detected skeleton. Each change that starts
// an analysis job hands it to ``onJob`` (the page follows it and redraws).

import { api } from "./api.js";
import { banner, fmt, h, messageOf } from "./ui.js";

const SITES = ["deltoid", "triceps", "biceps", "forearm"];

/**
 * A recording as GET /api/recordings/{id} answers (no response model yet: read untyped).
 * @typedef {any} RecordingDetail
 */
/**
 * Called with an analysis job a change started, the PATCH's answer and what to say of it.
 * @typedef {(job: import("./types").JobInfo, out?: any, said?: string) => void} OnJob
 */

/**
 * A small status line that says what happened, or the server's message.
 * @param {string} id the line's element id
 */
function statusLine(id) {
  const el = h("div", { id, class: "small", role: "status" });
  return {
    el,
    /** @param {string} text */
    busy(text) {
      el.className = "small muted";
      el.textContent = text;
    },
    /** @param {string} text */
    ok(text) {
      el.className = "small better";
      el.textContent = text;
    },
    /** @param {unknown} err what was caught */
    fail(err) {
      el.className = "small worse";
      el.setAttribute("role", "alert");
      el.textContent = messageOf(err);
    },
  };
}

/**
 * The rate check in the page's words (the reader's own sentence names the CLI's option): what
 * was measured, what it would be at the suggested rate. The button next to it applies it.
 * @param {{ median_frequency_hz: number, suggested_rate_hz: number, stored_rate_hz: number }} rc the rate check [Hz]
 * @returns {string}
 */
export function rateCheckText(rc) {
  const at = rc.median_frequency_hz * rc.suggested_rate_hz / rc.stored_rate_hz;
  return `Its EMG's spectral median is ${fmt(rc.median_frequency_hz, 3)} Hz, while surface EMG is typically 50–150 Hz; at ${fmt(rc.suggested_rate_hz)} Hz it would be ${fmt(at, 3)} Hz. `;
}

/**
 * The readers' warnings without the rate check's (shown once, with its fix).
 * @param {RecordingDetail} rec
 * @returns {string[]}
 */
export function otherWarnings(rec) {
  const rc = rec.rate_check;
  return (rec.warnings || []).filter((/** @type {string} */ w) => !(rc && w.includes(rc.reason)));
}

/**
 * The rate warning with its fix, and every reader warning (shown, not folded away).
 * @param {RecordingDetail} rec
 * @param {OnJob} onJob
 */
export function checksCard(rec, onJob) {
  /** @type {HTMLElement[]} */
  const parts = [];
  const rc = rec.rate_check;
  if (rc) {
    const status = statusLine("rate-status");
    const fix = h("button", { type: "button", class: "primary small", id: "rate-rerun" }, `Use ${fmt(rc.suggested_rate_hz)} Hz and re-analyse`);
    fix.addEventListener("click", async () => {
      fix.disabled = true;
      status.busy("Reading the files again at the suggested rate…");
      try {
        const out = await api(rc.rerun.url, { method: rc.rerun.method, body: rc.rerun.json });
        status.ok(`EMG rate set to ${fmt(rc.suggested_rate_hz)} Hz.`);
        if (out && out.analysis_job) onJob(out.analysis_job, out, `EMG rate set to ${fmt(rc.suggested_rate_hz)} Hz: the files were read again and are being re-analysed.`);
      } catch (err) {
        fix.disabled = false;
        status.fail(err);
      }
    });
    parts.push(h("div", { class: "banner warn", id: "rate-warning", role: "status" },
      h("strong", {}, `${rc.file}: the stored EMG rate (${fmt(rc.stored_rate_hz)} Hz) looks wrong. `),
      rateCheckText(rc), `Suggested: ${fmt(rc.suggested_rate_hz)} Hz (channels ${rc.channels.join(", ")}). `,
      fix, status.el));
  }
  const warnings = otherWarnings(rec);
  if (warnings.length) {
    parts.push(h("div", { id: "reader-warnings" }, h("strong", { class: "small" }, "What the readers noted"),
      h("ul", { class: "small" }, warnings.map((w) => h("li", {}, w)))));
  }
  return parts.length ? h("section", { class: "card", id: "checks-card" }, h("h2", {}, "Data checks"), parts) : null;
}

/** The analysis's "video size unknown" note (worded for the CLI: "--image-size W H"). */
export const IMAGE_SIZE_NOTE = /video size unknown/;

/** Common video sizes: the angles depend on the aspect ratio only (x is scaled by W/H). */
/** @type {[number, number, string][]} */
const VIDEO_SIZES = [[1280, 720, "16:9 landscape"], [720, 1280, "9:16 portrait (phone)"], [640, 480, "4:3"]];

/**
 * The image-size note with its one-click fix: each button sets the recording's image size,
 * reads the landmarks again and re-analyses; or the width and height typed in.
 * @param {RecordingDetail} rec
 * @param {string} note the analysis's note ("<source>: video size unknown ...")
 * @param {OnJob} onJob
 */
export function imageSizeFix(rec, note, onJob) {
  const source = note.split(":")[0];
  const status = statusLine("image-size-status");
  const width = h("input", { id: "image-width", type: "number", min: "1", max: "100000", step: "1", placeholder: "width", "aria-label": "Image width [px]", style: "width:90px" });
  const height = h("input", { id: "image-height", type: "number", min: "1", max: "100000", step: "1", placeholder: "height", "aria-label": "Image height [px]", style: "width:90px" });
  /** @type {HTMLButtonElement[]} */
  const buttons = [];
  /**
   * @param {number} w [px]
   * @param {number} hh [px]
   */
  async function apply(w, hh) {
    width.value = String(w);
    height.value = String(hh);
    buttons.forEach((b) => (b.disabled = true));
    status.busy(`Reading the landmarks again at ${w} × ${hh} px…`);
    try {
      const out = await api(`/api/recordings/${rec.id}`, { method: "PATCH", body: { image_size: [w, hh], analyse: true } });
      const said = `Image size set to ${w} × ${hh} px: the landmarks were read again and are being re-analysed.`;
      status.ok(said);
      if (out && out.analysis_job) onJob(out.analysis_job, out, said);
    } catch (err) {
      status.fail(err);
    } finally {
      buttons.forEach((b) => (b.disabled = false));
    }
  }
  VIDEO_SIZES.forEach(([w, hh, what], k) => buttons.push(h("button", { type: "button", class: `small${k === 0 ? " primary" : ""}`, id: `image-size-${w}x${hh}`, onclick: () => apply(w, hh) }, `${w} × ${hh} (${what})`)));
  const own = h("button", { type: "button", class: "small", id: "image-size-apply" }, "Use this size and re-analyse");
  own.addEventListener("click", () => {
    const w = Number(width.value);
    const hh = Number(height.value);
    if (!(Number.isInteger(w) && Number.isInteger(hh) && w >= 1 && hh >= 1 && w <= 100000 && hh <= 100000)) {
      status.fail(new Error("Image size: give the video's width and height in whole pixels (1 to 100,000)."));
      return;
    }
    apply(w, hh);
  });
  buttons.push(own);
  return h("div", { id: "image-size-fix" },
    `${source}: the video's size is unknown, so the angles come from the landmarks as if the frame were square (tens of degrees off for a 16:9 video). Give the size of the video MediaPipe ran on (only its aspect ratio matters): `,
    h("div", { class: "row", style: "margin-top:4px" }, ...buttons.slice(0, -1), width, "×", height, own),
    status.el);
}

/**
 * Muscle mapping and exclusions per channel; saving reads the files again and re-analyses.
 * @param {RecordingDetail} rec
 * @param {OnJob} onJob
 */
export function channelsCard(rec, onJob) {
  /** @type {import("./types").RecordingChannel[]} */
  const emg = rec.files.flatMap((/** @type {any} */ f) => f.channels.filter((/** @type {any} */ c) => c.kind === "emg").map((/** @type {any} */ c) => ({ ...c, file: f.original_name })));
  if (!emg.length) return null;
  const status = statusLine("channels-status");
  const rows = emg.map((c) => {
    const site = h("select", { "aria-label": `${c.name} site`, dataset: { channel: c.name } },
      h("option", { value: "none", selected: !c.site }, "not mapped"),
      SITES.map((s) => h("option", { value: s, selected: c.site === s }, s)));
    const exclude = h("input", { type: "checkbox", checked: c.excluded, "aria-label": `exclude ${c.name}`, dataset: { channel: c.name } });
    const note = c.flat ? "flat (an unused input): left out" : c.excluded ? "excluded by you" : "";
    return { c, site, exclude, row: h("tr", { dataset: { channel: c.name } },
      h("td", { class: "mono small" }, c.file), h("td", { class: "mono" }, c.name), h("td", {}, site),
      h("td", {}, exclude), h("td", { class: "small muted" }, note)) };
  });
  const save = h("button", { type: "button", class: "primary", id: "channels-save" }, "Save and re-analyse");
  save.addEventListener("click", async () => {
    /** @type {Record<string, string>} */
    const map = {};
    for (const r of rows) if ((r.c.site || "none") !== r.site.value) map[r.c.name] = r.site.value;
    const exclude = rows.filter((r) => r.exclude.checked).map((r) => r.c.name);
    /** @type {{ exclude_channels: string[], analyse: boolean, muscle_map?: Record<string, string> }} */
    const body = { exclude_channels: exclude, analyse: true };
    if (Object.keys(map).length) body.muscle_map = { ...(rec.options.muscle_map || {}), ...map };
    save.disabled = true;
    status.busy("Reading the files again with the new mapping…");
    try {
      const out = await api(`/api/recordings/${rec.id}`, { method: "PATCH", body });
      const saved = `Saved: ${exclude.length} channel(s) excluded${Object.keys(map).length ? `, ${Object.keys(map).length} remapped` : ""}.`;
      status.ok(saved);
      if (out.analysis_job) onJob(out.analysis_job, out, saved);
    } catch (err) {
      status.fail(err);
    } finally {
      save.disabled = false;
    }
  });
  return h("details", { class: "card", id: "channels-card" },
    h("summary", {}, h("strong", {}, "Channels: muscle mapping and exclusions"), h("span", { class: "small muted" }, ` ${emg.filter((c) => c.flat || c.excluded).length} of ${emg.length} EMG channels left out`)),
    h("div", { class: "table-wrap", style: "margin-top:8px" },
      h("table", { id: "channels-table" }, h("thead", {}, h("tr", {}, ["file", "channel", "EMG site", "exclude", "note"].map((t) => h("th", {}, t)))), h("tbody", {}, rows.map((r) => r.row)))),
    h("div", { class: "row", style: "margin-top:8px" }, save, status.el),
    h("p", { class: "small muted" }, "No upload again: the stored files are read with the new mapping and the analysis is run anew."));
}

/**
 * Every option of POST /api/analyses, with its default; "Run" starts a job with them.
 * @param {RecordingDetail} rec
 * @param {{ phase_bounds_deg: number[] }} defaults the analysis's defaults [deg]
 * @param {OnJob} onJob
 */
export function optionsCard(rec, defaults, onJob) {
  /**
   * @param {string} id
   * @param {number | null | undefined} value
   * @param {Record<string, string>} [attrs]
   */
  const num = (id, value, attrs = {}) => h("input", { id, type: "number", step: "any", value: value ?? "", ...attrs });
  const f = {
    emg_rate: num("opt-emg-rate", rec.options.emg_rate, { placeholder: "from the file" }),
    ab: num("opt-phase-ab", defaults.phase_bounds_deg[0]),
    bc: num("opt-phase-bc", defaults.phase_bounds_deg[1]),
    body_mass: num("opt-body-mass", 75),
    body_height: num("opt-body-height", 1.75),
    load_mass: num("opt-load", rec.load_kg, { placeholder: "12" }),
    offset: h("input", { id: "opt-offset", type: "text", placeholder: "none, a number [s] or auto" }),
    together: h("select", { id: "opt-together" },
      h("option", { value: "", selected: true }, `as uploaded (${rec.session === "together" ? "recorded together" : "separate trials"})`),
      h("option", { value: "true" }, "recorded together (one clock)"), h("option", { value: "false" }, "separate trials")),
    side: h("select", { id: "opt-side" }, ["auto", "left", "right"].map((s) => h("option", { value: s }, s))),
  };
  const status = statusLine("options-status");
  const run = h("button", { type: "button", class: "primary", id: "options-run" }, "Run the analysis with these options");
  run.addEventListener("click", async () => {
    /** @param {HTMLInputElement} el */
    const value = (el) => (el.value.trim() === "" ? null : Number(el.value));
    /** @type {Record<string, unknown>} */
    const body = {
      recording_id: rec.id,
      phase_bounds_deg: [value(f.ab), value(f.bc)],
      body_mass: value(f.body_mass),
      body_height: value(f.body_height),
      side: f.side.value,
    };
    if (value(f.emg_rate) !== null) body.emg_rate = value(f.emg_rate);
    if (value(f.load_mass) !== null) body.load_mass = value(f.load_mass);
    if (f.together.value) body.together = f.together.value === "true";
    const offset = f.offset.value.trim();
    if (offset) body.offset = offset === "auto" ? "auto" : Number(offset);
    run.disabled = true;
    status.busy("Starting…");
    try {
      const job = await api("/api/analyses", { method: "POST", body });
      status.ok(`Analysis job #${job.id} started.`);
      onJob(job);
    } catch (err) {
      status.fail(err);
    } finally {
      run.disabled = false;
    }
  });
  /**
   * @param {string} label
   * @param {HTMLElement} el
   * @param {string} [hint]
   */
  const field = (label, el, hint) => h("div", {}, h("label", { for: el.id }, label, hint ? h("span", { class: "hint" }, ` ${hint}`) : null), el);
  return h("details", { class: "card", id: "options-card" },
    h("summary", {}, h("strong", {}, "Analysis options"), h("span", { class: "small muted" }, " EMG rate, phase bounds, body, load, sessions, offset, side")),
    h("div", { class: "form-grid" },
      field("EMG rate", f.emg_rate, "[Hz]"), field("Phase A/B bound", f.ab, "[deg elbow flexion]"), field("Phase B/C bound", f.bc, "[deg]"),
      field("Body mass", f.body_mass, "[kg]"), field("Body height", f.body_height, "[m]"), field("Load", f.load_mass, "[kg]"),
      field("Files", f.together), field("EMG − pose offset", f.offset, "[s]"), field("Arm (pose)", f.side)),
    h("div", { class: "row", style: "margin-top:10px" }, run, status.el));
}

/**
 * A strip of video frames with the detected skeleton, for the user to check the fit.
 * @param {RecordingDetail} rec
 */
export function framesCard(rec) {
  /** @type {any[]} */
  const videos = rec.files.filter((/** @type {any} */ f) => f.role === "video");
  if (!videos.length) return null;
  const strip = h("div", { class: "frames", id: "skeleton-frames" });
  const note = h("div", { class: "small muted", id: "pose-note" });
  const card = h("section", { class: "card", id: "video-card" }, h("h2", {}, "Video: the detected pose"), note, strip);
  const describe = () => videos.map((v) => {
    const p = v.pose;
    if (!p) return `${v.original_name}: no pose extraction yet`;
    const r = p.result;
    return r ? `${v.original_name}: pose in ${r.frames_with_pose} of ${r.frames} frames at ${fmt(r.fps)} fps${r.warnings && r.warnings.length ? ` (${r.warnings.join("; ")})` : ""}` : `${v.original_name}: pose job #${p.job.id} ${p.job.state}${p.job.error ? `: ${p.job.error}` : ""}`;
  }).join(" · ");
  note.textContent = describe();
  if (rec.frames_url) {
    api(rec.frames_url).then((/** @type {{ frames: SkeletonFrame[] }} */ out) => {
      if (!out.frames.length) strip.append(banner("info", "No frame with a detected person to show."));
      out.frames.forEach((fr) => strip.append(h("figure", { class: personClass(/** @type {number} */ (fr.person)) },
        h("img", { src: fr.url, alt: `frame ${fr.frame} of ${fr.video} with the detected skeleton`, loading: "lazy" }),
        h("figcaption", { class: "small muted" }, `${fr.video}, frame ${fr.frame} (${fmt(fr.time_s, 3)} s)`),
        personLabel(fr))));
    }).catch((err) => strip.append(banner("warn", messageOf(err))));
  }
  return card;
}

/**
 * A video frame with the detected skeleton (GET the recording's `frames_url`).
 * @typedef {{ url: string, frame: number, video: string, time_s: number, person?: number | null,
 *   note?: string | null, quality?: number | null }} SkeletonFrame
 */

/**
 * Whom a skeleton frame shows, as the pose extraction decided (null: not recorded).
 * @param {SkeletonFrame} fr
 */
function personLabel(fr) {
  if (fr.person === null || fr.person === undefined) return null;
  const who = fr.note || (fr.person === 0 ? "the tracked person" : fr.person > 0 ? `not the tracked person (#${fr.person})` : "person unknown");
  const score = fr.quality === null || fr.quality === undefined ? "" : ` · quality ${fmt(fr.quality, 2)}`;
  return h("figcaption", { class: "small person-label", "data-person": String(fr.person) }, `${who}${score}`);
}

/** @param {number} person the frame's person (null/undefined give "" as well) */
function personClass(person) {
  return person === 0 ? "person-tracked" : person > 0 ? "person-other" : "";
}
