// Recordings: drag-and-drop upload of a session (one or more files) and the list.

import { api, followJob, qs, upload } from "./api.js";
import { otherWarnings, rateCheckText } from "./recording_panels.js";
import { banner, bytes, clear, clearFieldErrors, debounce, fmt, h, messageOf, namesInFormWords, showCaps, showFormErrors, when } from "./ui.js";

const SITES = ["deltoid", "triceps", "biceps", "forearm"];
/** The API's form fields in the words of this form. */
const FIELD_WORDS = {
  files: "Files", label: "Label", subject: "Subject", task: "Task", load_kg: "Load", notes: "Notes", session: "Recorded", condition: "Condition",
  muscle_map: "Muscle mapping", rate: "Sampling rate", emg_rate: "EMG rate", image_size: "Image size",
  frame_rate: "Frame rate", format: "Format",
};

/** The landmark presets of app.analysis.pose.LANDMARK_PRESETS (a test keeps the two equal). */
const LANDMARK_PRESETS = ["plugin_gait", "opencap", "pose2sim", "plugin_gait_right", "plugin_gait_left", "opencap_right", "opencap_left", "pose2sim_right", "pose2sim_left"];

const GUIDE_KEY = "bioplan.guide.hidden";

/** The first-visit guide: what BioPlan does and the demo one click away (hidden for good once
 * the user says so; kept in this browser's localStorage). */
function homeGuide() {
  if (localStorage.getItem(GUIDE_KEY) === "1") return null;
  const card = h("section", { class: "card guide", id: "home-guide" },
    h("h2", {}, "What BioPlan does"),
    h("p", {}, "People lifting a heavy dumbbell accelerate while the load is easy, carry the momentum through the posture where they are weakest, and let gravity finish the lift. BioPlan measures that in your recordings and plans robot motions that copy it, to save energy and cut peak power."),
    h("ol", {},
      h("li", {}, h("strong", {}, "Recordings: "), "upload surface EMG (deltoid, triceps, biceps, forearm) with pose from motion capture, MediaPipe or a video. The analysis finds the lifts, their A/B/C phases and the human template."),
      h("li", {}, h("strong", {}, "Plan: "), "on a built-in robot or your own URDF/MJCF, the paper's method, the best human-like motion, the physical bound and an industrial jerk-limited profile, side by side."),
      h("li", {}, h("strong", {}, "Compare: "), "every metric with its physical floor, the curves, the 3-D viewer with the recorded human beside the robot, and exports for robot controllers.")),
    h("div", { class: "row" },
      h("a", { class: "button primary", href: "#/compare", id: "guide-demo" }, "Open the demo comparison →"),
      h("a", { class: "button", href: "#/plan" }, "Plan a motion"),
      h("button", { type: "button", class: "small", id: "guide-hide", onclick: () => {
        localStorage.setItem(GUIDE_KEY, "1");
        card.remove();
      } }, "Hide this guide")));
  return card;
}

/**
 * A file chosen for the upload, with its list item and the line of its status.
 * @typedef {{ file: File, li: HTMLElement, status: HTMLElement }} ChosenFile
 */

/** @param {HTMLElement} main */
export function render(main) {
  /** @type {ChosenFile[]} */
  const files = []; // {file, li, status}
  /** @type {(() => void)[]} */
  const stops = []; // job followers to stop when the page is left
  let busy = false;

  // ---- upload card --------------------------------------------------------------------
  const input = h("input", { type: "file", multiple: true, hidden: true, id: "file-input", "aria-label": "Recording files" });
  const drop = h(
    "div",
    { class: "drop", id: "drop", tabindex: "0", role: "button", "aria-controls": "file-input" },
    h("strong", {}, "Drop recording files here"),
    h("div", { class: "small" }, "or click to choose · CSV, Noraxon, Delsys, Vicon, Qualisys, C3D, EDF/BDF, MAT, MediaPipe, OpenSim, XDF, videos (mp4, mov, avi)"),
  );
  const list = h("ul", { class: "files", id: "upload-files" });
  const topError = h("div", { id: "upload-error" });
  const bar = h("div", {});
  const progress = h("div", { class: "progress", hidden: true, id: "upload-progress", role: "progressbar", "aria-valuemin": "0", "aria-valuemax": "100" }, bar);
  const subject = h("input", { id: "subject", maxlength: "200", placeholder: "e.g. S01" });
  const task = h("input", { id: "task", maxlength: "200", placeholder: "e.g. dumbbell curl" });
  const load = h("input", { id: "load", type: "number", min: "0", max: "500", step: "0.1", placeholder: "kg" });
  const notes = h("textarea", { id: "notes", rows: "2", maxlength: "10000" });
  const label = h("input", { id: "rec-label", maxlength: "200", placeholder: "e.g. warm-up set" });
  const condition = h("input", { id: "condition", maxlength: "100", placeholder: "e.g. heavy (a cohort groups by it)" });
  const rate = h("input", { id: "rate", type: "number", min: "0", step: "any", placeholder: "from the file" });
  const emgRate = h("input", { id: "emg-rate", type: "number", min: "0", step: "any", placeholder: "from the file" });
  const frameRate = h("input", { id: "frame-rate", type: "number", min: "0", step: "any", placeholder: "video landmarks" });
  const imageSize = h("input", { id: "image-size", pattern: "\\d+x\\d+", placeholder: "e.g. 1280x720" });
  const landmarkPreset = h("select", { id: "landmark-preset" },
    h("option", { value: "", selected: true }, "automatic (MediaPipe, Plug-in Gait LSHO/LELB/LWRA+LWRB...)"),
    LANDMARK_PRESETS.map((p) => h("option", { value: p }, p)));
  const landmarkMap = h("input", { id: "landmark-map", maxlength: "1000", placeholder: "or shoulder=RSHO,elbow=RELB,wrist=RWRA" });
  const sessionMode = h("select", { id: "session" },
    h("option", { value: "separate", selected: true }, "separate trials (each file on its own clock)"),
    h("option", { value: "together" }, "recorded together (one clock, e.g. EMG and the video of the same lifts)"));
  const maps = h("div", { id: "muscle-map" });
  const addMap = (label = "", site = "biceps") => {
    const row = h(
      "div",
      { class: "map-row" },
      h("input", { placeholder: "channel label, e.g. Biceps.EMG4", value: label, "aria-label": "Channel label" }),
      h("select", { "aria-label": "EMG site" }, SITES.map((s) => h("option", { value: s, selected: s === site }, s))),
      h("button", { type: "button", class: "small", title: "Remove", onclick: () => row.remove() }, "×"),
    );
    maps.append(row);
  };
  const submit = h("button", { class: "primary", type: "submit", id: "upload-button", disabled: true }, "Upload");
  /** The request's fields and their inputs: a refusal is shown beside each, caps as hints. */
  const inputs = { subject, task, load_kg: load, notes, label, condition, rate, emg_rate: emgRate, frame_rate: frameRate, image_size: imageSize };

  /** @param {boolean} value */
  function setBusy(value) {
    busy = value;
    submit.disabled = value || files.length === 0;
  }

  /** @param {FileList | File[]} fileList */
  function addFiles(fileList) {
    if (busy) return;
    for (const file of fileList) {
      if (files.some((f) => f.file.name === file.name && f.file.size === file.size)) continue;
      const status = h("div", {});
      const li = h(
        "li",
        { dataset: { name: file.name } },
        h("div", { class: "row" },
          h("span", { class: "name" }, file.name),
          h("span", { class: "meta" }, bytes(file.size)),
          h("button", { type: "button", class: "small", style: "margin-left:auto", title: "Remove", onclick: () => {
            if (busy) return;
            files.splice(files.findIndex((f) => f.li === li), 1);
            li.remove();
            setBusy(false);
          } }, "×"),
        ),
        status,
      );
      files.push({ file, li, status });
      list.append(li);
    }
    setBusy(false);
  }

  input.addEventListener("change", () => {
    addFiles(/** @type {FileList} */ (input.files));
    input.value = "";
  });
  drop.addEventListener("click", () => input.click());
  drop.addEventListener("keydown", (e) => {
    if (e.key === "Enter" || e.key === " ") {
      e.preventDefault();
      input.click();
    }
  });
  drop.addEventListener("dragover", (e) => {
    e.preventDefault();
    drop.classList.add("over");
  });
  drop.addEventListener("dragleave", () => drop.classList.remove("over"));
  drop.addEventListener("drop", (e) => {
    e.preventDefault();
    drop.classList.remove("over");
    addFiles(/** @type {DataTransfer} */ (e.dataTransfer).files);
  });

  function muscleMap() {
    /** @type {Record<string, string>} */
    const out = {};
    for (const row of maps.querySelectorAll(".map-row")) {
      const [labelInput, siteSelect] = /** @type {NodeListOf<HTMLInputElement | HTMLSelectElement>} */ (row.querySelectorAll("input, select"));
      const label = labelInput.value.trim();
      if (label) out[label] = siteSelect.value;
    }
    return Object.keys(out).length ? JSON.stringify(out) : null;
  }

  /** The next upload starts from empty fields: nothing of this session carries over. */
  function resetFields() {
    [label, subject, task, load, notes, condition, rate, emgRate, frameRate, imageSize, landmarkPreset, landmarkMap].forEach((el) => (el.value = ""));
    sessionMode.value = "separate";
    clear(maps);
  }

  /** What the server says of a stored session: the rate check with its one-click fix, the
   * readers' warnings, the pose jobs of videos (then the analysis), or the analysis job.
   * @param {any} rec the stored recording (POST /api/recordings; no response model yet)
   * @param {string} landmarks the analysis's landmark map or preset, or ""
   */
  function showStored(rec, landmarks) {
    const note = banner("info", `Stored as recording #${rec.id}. `);
    note.id = "upload-stored";
    note.append(h("a", { href: `#/recordings/${rec.id}` }, "Open it"));
    topError.append(note);
    if (rec.rate_check) topError.append(rateCheck(rec));
    const warnings = otherWarnings(rec); // the rate check's is said once, with its fix
    if (warnings.length) {
      topError.append(h("div", { class: "banner warn", id: "upload-warnings" }, h("strong", {}, "The readers noted:"), h("ul", { class: "small" }, warnings.map((/** @type {string} */ w) => h("li", {}, w)))));
    }
    if (rec.pose_jobs && rec.pose_jobs.length) {
      rec.pose_jobs.forEach((/** @type {import("./types").JobInfo} */ job) => topError.append(poseProgress(rec, job)));
      return; // the server analyses the recording once the landmarks are stored
    }
    api("/api/analyses", { method: "POST", body: landmarks ? { recording_id: rec.id, landmarks } : { recording_id: rec.id } })
      .then((job) => note.append(` · analysis job #${job.id} started`))
      .catch((err) => topError.append(banner("warn", `The analysis could not be started: ${messageOf(err)}`)));
  }

  /** @param {any} rec the stored recording, with its `rate_check` */
  function rateCheck(rec) {
    const rc = rec.rate_check;
    const status = h("span", { class: "small", id: "upload-rate-status" });
    const fix = h("button", { type: "button", class: "small primary", id: "upload-rate-rerun" }, `Use ${fmt(rc.suggested_rate_hz)} Hz and analyse`);
    fix.addEventListener("click", async () => {
      fix.disabled = true;
      try {
        const out = await api(rc.rerun.url, { method: rc.rerun.method, body: rc.rerun.json });
        status.textContent = ` Done: read again at ${fmt(rc.suggested_rate_hz)} Hz${out.analysis_job ? `, analysis job #${out.analysis_job.id} started` : ""}.`;
      } catch (err) {
        fix.disabled = false;
        status.textContent = ` ${messageOf(err)}`;
      }
    });
    return h("div", { class: "banner warn", id: "upload-rate-warning", role: "status" },
      h("strong", {}, `${rc.file}: the stored EMG rate (${fmt(rc.stored_rate_hz)} Hz) looks wrong. `),
      rateCheckText(rc), `Suggested: ${fmt(rc.suggested_rate_hz)} Hz. `, fix, status);
  }

  /**
   * A video's pose extraction: frames done of total, then a link to check the skeletons.
   * @param {{ id: number }} rec
   * @param {import("./types").JobInfo} job
   */
  function poseProgress(rec, job) {
    const bar = h("div", {});
    const text = h("span", { class: "small" }, "pose: queued");
    const box = h("div", { class: "pose-job", dataset: { job: String(job.id) } }, text, h("div", { class: "progress" }, bar));
    const follow = followJob(job, (j) => {
      bar.style.width = `${Math.round(100 * j.progress)}%`;
      // Frames are counted once the worker reads them (before that, the job reports 0 of 1).
      const frames = j.stage === "pose" && j.of > 1 ? `, ${j.done.toLocaleString("en-US")} of ${j.of.toLocaleString("en-US")} frames` : j.state === "running" ? ", starting" : "";
      text.textContent = `pose job #${j.id}: ${j.state}${frames}${j.error ? `: ${j.error}` : ""}`;
    });
    stops.push(follow.stop);
    follow.done.then((final) => {
      /** @type {HTMLElement} */ (bar.parentElement).classList.add(final.state === "succeeded" ? "done" : "failed");
      if (final.state === "succeeded") box.append(h("a", { href: `#/recordings/${rec.id}`, class: "small" }, "Check the detected skeletons and the analysis →"));
    });
    return box;
  }

  /** @param {SubmitEvent} e */
  async function onSubmit(e) {
    e.preventDefault();
    if (!files.length || busy) return;
    setBusy(true);
    clear(topError);
    clearFieldErrors(inputs);
    files.forEach((f) => clear(f.status));
    const sent = [...files];
    const form = new FormData();
    sent.forEach((f) => form.append("files", f.file, f.file.name));
    const fields = { session: sessionMode.value, label: label.value, subject: subject.value, task: task.value, load_kg: load.value, notes: notes.value, condition: condition.value, rate: rate.value, emg_rate: emgRate.value, frame_rate: frameRate.value, image_size: imageSize.value, muscle_map: muscleMap() };
    for (const [k, v] of Object.entries(fields)) if (v !== null && String(v).trim() !== "") form.append(k, String(v).trim());
    const landmarks = landmarkMap.value.trim() || landmarkPreset.value; // an analysis option
    progress.hidden = false;
    progress.className = "progress";
    bar.style.width = "0%";
    try {
      const rec = await upload("/api/recordings", form, (f) => {
        bar.style.width = `${Math.round(100 * f)}%`;
        progress.setAttribute("aria-valuenow", String(Math.round(100 * f)));
      });
      bar.style.width = "100%";
      progress.classList.add("done");
      // Only the files sent leave the list: one added meanwhile stays, with its own status.
      sent.forEach((f) => {
        f.li.remove();
        files.splice(files.indexOf(f), 1);
      });
      resetFields();
      showStored(rec, landmarks);
      refresh();
    } catch (err) {
      progress.classList.add("failed");
      bar.style.width = "100%";
      /** @type {import("./types").Problem} */
      const problem = err.problem || {};
      // The server names every file it could not read (or the one, for other refusals).
      const named = problem.files || (problem.file ? [{ file: problem.file, detail: messageOf(err) }] : []);
      const culprits = /** @type {[ChosenFile, string][]} */ (named.map((n) => [files.find((f) => f.file.name === n.file), n.detail]).filter(([f]) => f));
      if (culprits.length) {
        // Each message next to its file; the others were not stored either.
        culprits.forEach(([f, detail]) => f.status.append(h("div", { class: "file-error", role: "alert" }, namesInFormWords(detail, FIELD_WORDS))));
        const bad = new Set(culprits.map(([f]) => f));
        sent.filter((f) => !bad.has(f)).forEach((f) => f.status.append(h("div", { class: "meta" }, "not stored: a session is stored whole or not at all")));
        const which = culprits.map(([f]) => f.file.name).join(", ");
        topError.append(banner("error", `Nothing was stored: ${culprits.length > 1 ? `${culprits.length} files` : which} could not be read (${culprits.length > 1 ? `${which}; each message is next to its file` : "its message is next to it"}).`));
      } else {
        showFormErrors(topError, err, FIELD_WORDS, inputs);
      }
    } finally {
      setBusy(false);
    }
  }

  const uploadCard = h(
    "form",
    { class: "card", id: "upload-form", onsubmit: onSubmit, novalidate: true },
    h("h2", {}, "Upload a recording session"),
    drop,
    input,
    list,
    progress,
    topError,
    h("div", { class: "fields" },
      h("div", {}, h("label", { for: "subject" }, "Subject"), subject),
      h("div", {}, h("label", { for: "task" }, "Task"), task),
      h("div", {}, h("label", { for: "load" }, "Load ", h("span", { class: "hint" }, "[kg]")), load),
      h("div", {}, h("label", { for: "condition" }, "Condition"), condition),
      h("div", { class: "wide" }, h("label", { for: "rec-label" }, "Label ", h("span", { class: "hint" }, "(optional)")), label),
      h("div", { class: "wide" }, h("label", { for: "notes" }, "Notes"), notes),
      h("div", { class: "wide" }, h("label", { for: "session" }, "The files were"), sessionMode),
    ),
    h("details", {},
      h("summary", {}, "Muscle mapping, rates, video size, arm markers"),
      h("p", { class: "small muted" }, "Map channel labels to the four EMG sites when the file's names are not recognised; override a sampling rate the file states wrongly; give the frame rate and image size of pose landmarks exported without them."),
      maps,
      h("button", { type: "button", class: "small", style: "margin-top:6px", onclick: () => addMap() }, "+ mapping"),
      h("div", { class: "fields" },
        h("div", {}, h("label", { for: "rate" }, "Sampling rate ", h("span", { class: "hint" }, "[Hz], of files that state none")), rate),
        h("div", {}, h("label", { for: "emg-rate" }, "EMG rate ", h("span", { class: "hint" }, "[Hz], replaces the EMG rate a file states")), emgRate),
        h("div", {}, h("label", { for: "frame-rate" }, "Frame rate ", h("span", { class: "hint" }, "[fps]")), frameRate),
        h("div", {}, h("label", { for: "image-size" }, "Image size ", h("span", { class: "hint" }, "[px]")), imageSize),
        h("div", {}, h("label", { for: "landmark-preset" }, "Arm markers ", h("span", { class: "hint" }, "which are shoulder, elbow, wrist")), landmarkPreset),
        h("div", {}, h("label", { for: "landmark-map" }, "Marker mapping ", h("span", { class: "hint" }, "role=NAME, overrides the preset")), landmarkMap),
      ),
    ),
    h("div", { class: "row", style: "margin-top:14px" }, submit, h("span", { class: "small muted" }, "All files of a session are stored together.")),
  );

  // ---- list card ----------------------------------------------------------------------
  const search = h("input", { type: "search", id: "search", placeholder: "Search labels, subject, condition, task, notes, file names", "aria-label": "Search recordings" });
  const tbody = h("tbody", { id: "recordings-body" });
  const total = h("span", { class: "muted small" });
  const listError = h("div", {});
  const listCard = h(
    "section",
    { class: "card" },
    h("div", { class: "page-head" }, h("h2", {}, "Recordings"), total),
    search,
    listError,
    h("div", { class: "table-wrap", style: "margin-top:10px" },
      h("table", { id: "recordings-table" },
        // Task, files and date give way on a narrow window, so Open and Delete stay in view.
        h("thead", {}, h("tr", {}, ["#", "Subject", "Task", "Load", "Files", "Created", ""].map((c, i) => h("th", { class: `${i === 3 ? "num" : ""}${[2, 4, 5].includes(i) ? " wide-only" : ""}` }, c)))),
        tbody,
      ),
    ),
  );

  /** @param {any} rec a listed recording (GET /api/recordings) */
  async function remove(rec) {
    if (!confirm(`Delete recording #${rec.id} (${rec.file_names.join(", ")})? Its files are removed too.`)) return;
    try {
      await api(`/api/recordings/${rec.id}`, { method: "DELETE" });
      refresh();
    } catch (err) {
      clear(listError).append(banner("error", messageOf(err)));
    }
  }

  async function refresh() {
    try {
      const page = await api(`/api/recordings${qs({ q: search.value.trim(), limit: 100 })}`);
      clear(listError);
      clear(tbody);
      const q = search.value.trim();
      const n = `${page.total} recording${page.total === 1 ? "" : "s"}`;
      total.textContent = q ? `${n} match${page.total === 1 ? "es" : ""} “${q}”` : `${n} in all`;
      if (!page.items.length) {
        tbody.append(h("tr", {}, h("td", { colspan: "7", class: "muted" }, search.value ? "No recording matches." : "No recordings yet: drop files on the left.")));
      }
      for (const rec of page.items) {
        const open = () => (location.hash = `#/recordings/${rec.id}`);
        tbody.append(
          h("tr", { class: "click", dataset: { id: rec.id } },
            h("td", { class: "mono", onclick: open }, rec.id),
            h("td", { onclick: open }, rec.label ? h("div", { class: "rec-label" }, h("strong", {}, rec.label)) : null, rec.subject || h("span", { class: "muted" }, "–"), rec.condition ? h("div", { class: "small muted rec-condition" }, `condition: ${rec.condition}`) : null),
            h("td", { class: "wide-only", onclick: open }, rec.task || h("span", { class: "muted" }, "–")),
            h("td", { class: "num", onclick: open }, rec.load_kg === null ? "–" : `${rec.load_kg} kg`),
            h("td", { class: "wide-only", onclick: open }, h("div", { class: "mono" }, rec.file_names.join(", ")), h("div", { class: "small muted" }, rec.formats.join(", "))),
            h("td", { class: "nowrap small wide-only", onclick: open }, when(rec.created_at)),
            h("td", { class: "nowrap" },
              h("a", { class: "button small", href: `#/recordings/${rec.id}` }, "Open"), " ",
              h("button", { type: "button", class: "small danger", onclick: () => remove(rec), "aria-label": `Delete recording ${rec.id}` }, "Delete"),
            ),
          ),
        );
      }
    } catch (err) {
      clear(listError).append(banner("error", `The list could not be loaded: ${messageOf(err)}`));
    }
  }
  search.addEventListener("input", debounce(refresh, 250));

  showCaps("upload", { load_kg: load, rate, emg_rate: emgRate, frame_rate: frameRate });
  const guide = homeGuide();
  if (guide) main.append(guide);
  main.append(h("div", { class: "grid-2" }, uploadCard, listCard));
  refresh();
  return () => stops.forEach((stop) => stop());
}
