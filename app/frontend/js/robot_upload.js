// "Add your robot" on the Plan page: a URDF, an MJCF, or a zip of the robot's folder (meshes
// resolved from package:// paths), a motor sidecar, which joints play the human shoulder and
// elbow, and joints locked at values. The robot's joints are read from the chosen file in the
// browser to offer them by name; the server checks everything again and its message is shown
// in words, next to the field it concerns.

import { upload } from "./api.js";
import { h, messageOf } from "./ui.js";

/**
 * The API's field names in the words of the form.
 * @type {Record<string, string>}
 */
const FIELD_WORDS = {
  name: "Name", urdf: "Model file (URDF)", mjcf: "Model file (MJCF)", package: "Model file (zip)",
  sidecar: "Motor sidecar", payload: "Payload", shoulder_joint: "Shoulder joint",
  elbow_joint: "Elbow joint", lock: "Locked joints", base_link: "Arm base link",
};

/**
 * The movable joints of a URDF or MJCF text: [{name, kind: "revolute"|"prismatic"}].
 * @param {string} text
 */
export function movableJoints(text) {
  const doc = new DOMParser().parseFromString(text, "application/xml");
  if (doc.querySelector("parsererror")) return [];
  if (doc.documentElement.nodeName === "robot") {
    return [...doc.querySelectorAll("robot > joint")]
      .filter((j) => !["fixed", "floating", "planar"].includes(j.getAttribute("type") || ""))
      .map((j) => ({ name: j.getAttribute("name"), kind: j.getAttribute("type") === "prismatic" ? "prismatic" : "revolute" }));
  }
  return [...doc.querySelectorAll("joint")]
    .filter((j) => j.getAttribute("name") && !["free", "ball"].includes(j.getAttribute("type") || ""))
    .map((j) => ({ name: j.getAttribute("name"), kind: j.getAttribute("type") === "slide" ? "prismatic" : "revolute" }));
}

/**
 * The upload field a model file goes in, by its extension; null for none.
 * @param {File} file
 * @returns {string | null}
 */
function modelField(file) {
  const ext = file.name.toLowerCase().split(".").pop();
  return /** @type {Record<string, string>} */ ({ urdf: "urdf", xml: "mjcf", mjcf: "mjcf", zip: "package" })[ext || ""] || null;
}

/** Millimetres or centimetres of a depth [m], in words. */
/** @param {number} depth [m] */
function depthWords(depth) {
  return depth >= 0.1 ? `${(100 * depth).toFixed(0)} cm` : `${(1000 * depth).toFixed(0)} mm`;
}

/**
 * What the upload card says about the default task's safety check (``RobotInfo.default_task_safety``):
 * ``{bad, text}``, or null when the server sent no check (a robot stored before it existed).
 * @param {any} check
 * @returns {{bad: boolean, text: string} | null}
 */
export function defaultTaskWarning(check) {
  if (!check) return null;
  if (check.checked !== true) {
    return { bad: false, text: `The default task was not checked for collisions (${check.reason || "not checked"}).` };
  }
  const worst = check.worst;
  if (check.ok === true || !worst) return null;
  const links = worst.links || [];
  const at = `at t = ${Number(worst.deepest_time).toFixed(2)} s of a ${check.duration} s quintic`;
  const depth = depthWords(Number(worst.depth));
  let what;
  if (worst.kind === "plane") what = `drives ${links[0]} ${depth} below the ${worst.obstacle || "mount plane"}`;
  else if (worst.kind === "obstacle") what = `drives ${links[0]} ${depth} into obstacle “${worst.obstacle}”`;
  else what = `drives ${links[0]} ${depth} into ${links[links.length - 1]}`;
  const more = check.findings > 1 ? ` (${check.findings} contacts in all)` : "";
  return {
    bad: true,
    text: `Unsafe default task: it ${what} ${at}${more}. Give start and goal angles that keep clear, or a sidecar mount plane or obstacles that match the cell, before planning it.`,
  };
}

/**
 * The card; ``onAdded(robot)`` is called with the stored robot (``RobotInfo``).
 * @param {(robot: any) => void} onAdded
 * @returns {HTMLDetailsElement}
 */
export function robotUploadCard(onAdded) {
  const name = h("input", { id: "robot-name", type: "text", required: true, pattern: "[A-Za-z0-9_.\\-]{1,100}", title: "letters, digits, _, . and - (no spaces)", placeholder: "e.g. my_ur5", "aria-label": "Robot name" });
  const model = h("input", { id: "robot-model", type: "file", accept: ".urdf,.xml,.mjcf,.zip", "aria-label": "Model file" });
  const mjcf = h("input", { id: "robot-mjcf", type: "file", accept: ".xml,.mjcf", "aria-label": "MJCF for simulation (optional)" });
  const sidecar = h("input", { id: "robot-sidecar", type: "file", accept: ".yaml,.yml", "aria-label": "Motor sidecar (optional)" });
  const payload = h("input", { id: "robot-payload", type: "number", min: "0", max: "10000", step: "0.1", placeholder: "none", "aria-label": "Default payload [kg]" });
  const jointList = h("datalist", { id: "robot-joint-names" });
  const shoulder = h("input", { id: "robot-shoulder", type: "text", list: "robot-joint-names", placeholder: "auto", "aria-label": "Shoulder joint" });
  const elbow = h("input", { id: "robot-elbow", type: "text", list: "robot-joint-names", placeholder: "auto", "aria-label": "Elbow joint" });
  const baseLink = h("input", { id: "robot-base-link", type: "text", placeholder: "only for legged, mobile or two-arm robots", "aria-label": "Arm base link" });
  const tipLink = h("input", { id: "robot-tip-link", type: "text", placeholder: "only when the arm branches (a hand)", "aria-label": "Arm tip link" });
  const locks = h("div", { id: "robot-locks", class: "stack" });
  const found = h("div", { class: "small muted", id: "robot-joints-found" });
  const status = h("div", { id: "robot-upload-status", role: "status", class: "small" });
  const button = h("button", { type: "submit", class: "primary", id: "robot-upload" }, "Add the robot");
  const warning = h("div", { id: "robot-upload-safety", class: "small" });
  let joints = [];

  const addLock = () => {
    const joint = h("input", { type: "text", list: "robot-joint-names", class: "lock-joint", placeholder: "joint", "aria-label": "Joint to lock" });
    const value = h("input", { type: "number", step: "any", class: "lock-value", placeholder: "deg (m if prismatic)", "aria-label": "Locked value" });
    const row = h("div", { class: "row" }, joint, value, h("button", { type: "button", class: "small", onclick: () => row.remove() }, "remove"));
    locks.append(row);
  };

  model.addEventListener("change", async () => {
    const file = /** @type {FileList} */ (model.files)[0];
    jointList.replaceChildren();
    joints = [];
    found.textContent = "";
    if (!file) return;
    if (!modelField(file)) {
      found.textContent = "Expected a .urdf, an MJCF .xml or a .zip of the robot's folder.";
      found.className = "small worse";
      return;
    }
    if (!name.value) name.value = file.name.replace(/\.[^.]+$/, "").replace(/[^A-Za-z0-9_-]/g, "_").slice(0, 64);
    if (modelField(file) === "package") {
      found.textContent = "A zip: the server reads the joints from the model inside.";
      found.className = "small muted";
      return;
    }
    joints = movableJoints(await file.text());
    joints.forEach((j) => jointList.append(h("option", { value: j.name }, j.kind)));
    found.className = "small muted";
    found.textContent = joints.length ? `${joints.length} movable joints: ${joints.map((j) => j.name).join(", ")}` : "No movable joint found in this file.";
  });

  const form = h("form", { id: "robot-form", class: "form-grid", novalidate: true },
    h("div", {}, h("label", { for: "robot-name" }, "Name"), name),
    h("div", {}, h("label", { for: "robot-model" }, "Model: URDF, MJCF or zip with meshes"), model, found),
    h("div", {}, h("label", { for: "robot-mjcf" }, "MJCF for simulation (optional, with a URDF)"), mjcf),
    h("div", {}, h("label", { for: "robot-sidecar" }, "Motor, gear and payload sidecar (optional YAML, docs/robots.md)"), sidecar),
    h("div", {}, h("label", { for: "robot-payload" }, "Default payload [kg]"), payload),
    h("div", {}, h("label", { for: "robot-shoulder" }, "Joint that plays the human shoulder"), shoulder),
    h("div", {}, h("label", { for: "robot-elbow" }, "Joint that plays the human elbow"), elbow),
    h("div", {}, h("label", { for: "robot-base-link" }, "Arm base link (a robot whose joints branch)"), baseLink),
    h("div", {}, h("label", { for: "robot-tip-link" }, "Arm tip link (optional, with the base link)"), tipLink),
    h("div", {}, h("label", {}, "Locked joints (fingers, grippers, a torso)"), locks, h("button", { type: "button", class: "small", id: "robot-add-lock", onclick: addLock }, "+ lock a joint")),
    jointList,
    h("div", { class: "row" }, button, status),
    warning,
  );

  form.addEventListener("submit", async (event) => {
    event.preventDefault();
    status.className = "small";
    warning.textContent = "";
    const file = /** @type {FileList} */ (model.files)[0];
    if (!name.value.trim()) return fail("Name: give the robot a name (letters, digits, _ and -).");
    // Said in words here: the server's refusal quotes its pattern (a regular expression).
    if (!/^[A-Za-z0-9_.-]{1,100}$/.test(name.value.trim())) return fail(`Name: “${name.value.trim()}” may hold only letters, digits, _, . and - (no spaces), at most 100 characters; e.g. ${name.value.trim().replace(/[^A-Za-z0-9_.-]+/g, "_").slice(0, 100)}.`);
    if (!file || !modelField(file)) return fail(`${FIELD_WORDS.urdf}: choose a .urdf, an MJCF .xml or a .zip of the robot's folder.`);
    const body = new FormData();
    body.append("name", name.value.trim());
    body.append(/** @type {string} */ (modelField(file)), file);
    const [mjcfFile] = /** @type {FileList} */ (mjcf.files);
    if (mjcfFile) body.append("mjcf", mjcfFile);
    const [sidecarFile] = /** @type {FileList} */ (sidecar.files);
    if (sidecarFile) body.append("sidecar", sidecarFile);
    if (payload.value !== "") body.append("payload", payload.value);
    if (shoulder.value.trim()) body.append("shoulder_joint", shoulder.value.trim());
    if (elbow.value.trim()) body.append("elbow_joint", elbow.value.trim());
    if (baseLink.value.trim()) body.append("base_link", baseLink.value.trim());
    if (tipLink.value.trim()) body.append("tip_link", tipLink.value.trim());
    for (const row of locks.querySelectorAll(".row")) {
      const joint = /** @type {HTMLInputElement} */ (row.querySelector(".lock-joint")).value.trim();
      const value = /** @type {HTMLInputElement} */ (row.querySelector(".lock-value")).value;
      if (!joint && value === "") continue;
      if (!joint || value === "") return fail(`${FIELD_WORDS.lock}: each lock needs a joint and a value.`);
      body.append("lock", `${joint}=${value}`);
    }
    button.disabled = true;
    status.textContent = "Uploading…";
    try {
      const robot = await upload("/api/robots", body, (f) => {
        status.textContent = f < 1 ? `Uploading… ${Math.round(100 * f)} %` : "Checking the model…";
      });
      status.className = "small better";
      status.textContent = `Added ${robot.name}: ${robot.joint_names.length} joints (${robot.joint_names.join(", ")}).`;
      const missing = robot.missing_meshes || [];
      if (missing.length) {
        // The viewer would draw these links without bodies: ask for the meshes now.
        status.className = "small worse";
        status.textContent += ` ${missing.length} mesh file(s) the URDF names are missing (${missing.slice(0, 3).join(", ")}${missing.length > 3 ? ", …" : ""}): upload a .zip of the robot's folder with its meshes to see its bodies in the viewer.`;
      }
      const safety = defaultTaskWarning(robot.default_task_safety);
      warning.className = safety ? `small ${safety.bad ? "worse" : "muted"}` : "small";
      warning.textContent = safety ? safety.text : "";
      onAdded(robot);
    } catch (err) {
      const field = err.problem && err.problem.field;
      fail(field && FIELD_WORDS[field] ? `${FIELD_WORDS[field]}: ${messageOf(err)}` : messageOf(err));
    } finally {
      button.disabled = false;
    }
  });

  /** @param {string} text */
  function fail(text) {
    status.className = "small worse";
    status.setAttribute("role", "alert");
    status.textContent = text;
  }

  return h("details", { class: "card", id: "robot-upload-card" },
    h("summary", {}, h("strong", {}, "Add your robot"), h("span", { class: "small muted" }, " URDF, MJCF or a zip with meshes; shoulder and elbow joints; locks; motors")),
    form);
}
