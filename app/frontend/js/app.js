// The dashboard shell: hash routes, navigation, service status, API token.

import { api, setToken, token } from "./api.js";
import { mountJobDrawer } from "./jobs_drawer.js";
import { loadNames } from "./names.js";
import { colours } from "./plots.js";
import { banner, clear, h, messageOf } from "./ui.js";

const routes = [
  { re: /^#\/recordings\/(\d+)$/, page: "recordings", load: () => import("./recording.js") },
  { re: /^#\/recordings\/?$/, page: "recordings", load: () => import("./recordings.js") },
  { re: /^#\/plan\/?(?:\?(.*))?$/, page: "plan", load: () => import("./plan.js") },
  { re: /^#\/cohort(?:\/(\d+))?\/?$/, page: "cohort", load: () => import("./cohort.js") },
  { re: /^#\/validate(?:\/(\d+))?\/?$/, page: "validate", load: () => import("./validate.js") },
  // Trade-offs under Compare: the Pareto fronts (front.js), one reopened by its id.
  { re: /^#\/compare\/fronts(?:\/(\d+))?\/?$/, page: "compare", load: () => import("./front.js") },
  // Query: ?methods=a,b (the pair shown), ?sweep=ID (that sweep's heat maps).
  { re: /^#\/?compare(?:\/(plan|simulation)\/(\d+))?\/?(?:\?(.*))?$/, page: "compare", load: () => import("./compare.js") },
];

const main = /** @type {HTMLElement} */ (document.getElementById("app"));
/** @type {(() => void) | null} */
let current = null; // the page's cleanup function
let drawerMounted = false;
let visits = 0; // which route() call is the latest

async function route() {
  const hash = location.hash || "#/recordings";
  const match = /** @type {[typeof routes[number], RegExpMatchArray] | undefined} */ (routes.map((r) => [r, hash.match(r.re)]).find(([, m]) => m));
  const visit = ++visits;
  if (current) {
    try {
      current();
    } catch {
      /* a page that failed to clean up must not block the next one */
    }
    current = null;
  }
  /** @type {NodeListOf<HTMLAnchorElement>} */ (document.querySelectorAll(".tabs a")).forEach((a) => a.classList.toggle("active", match && a.dataset.page === match[0].page));
  clear(main);
  if (!match) {
    main.append(banner("error", `No page at ${hash}.`));
    return;
  }
  const [r, m] = match;
  // Each visit renders into its own box: a page still loading when the visitor moves on (the
  // Compare page's link to the trade-offs, a tab) goes on filling its own detached box, not the
  // next page, and its cleanup runs as soon as it is known.
  const view = h("div", { class: "page-view" });
  main.append(view);
  try {
    await loadNames();
    if (!drawerMounted) {
      // The job drawer reads the shared job states, so it is mounted once they are loaded.
      mountJobDrawer(/** @type {HTMLElement} */ (document.getElementById("jobs-button")), /** @type {HTMLElement} */ (document.getElementById("job-drawer")));
      drawerMounted = true;
    }
    // The stylesheet's trajectory colours follow the shared names too.
    for (const [k, v] of Object.entries({ "--std": colours().standard, "--opt": colours().optimized })) {
      document.documentElement.style.setProperty(k, v);
    }
    // Every page module renders into its box from the route's captured groups.
    const mod = /** @type {{ render: (main: HTMLElement, args: string[]) => Promise<any> }} */ (await r.load());
    const cleanup = (await mod.render(view, m.slice(1))) || null;
    if (visit === visits) current = cleanup;
    else if (cleanup) cleanup();
  } catch (err) {
    view.append(banner("error", `This page could not be shown: ${messageOf(err)}`));
  }
  main.focus({ preventScroll: true });
}

let active = 0; // jobs the drawer sees queued or running (its stream is live; health is polled)
async function status() {
  const dot = /** @type {HTMLElement} */ (document.getElementById("status-dot"));
  const text = /** @type {HTMLElement} */ (document.getElementById("status-text"));
  try {
    const [health, viewer] = await Promise.all([api("/api/health"), api("/api/viewer")]);
    dot.className = `dot ${health.status === "ok" ? "ok" : "bad"}`;
    const busy = [health.running ? `${health.running} running` : "", health.queued ? `${health.queued} queued` : ""].filter(Boolean);
    const jobs = busy.length ? busy.join(", ") : active ? `${active} job(s) active` : "idle";
    text.textContent = `${health.executor} executor, ${jobs} · viewer ${viewer.enabled ? `:${viewer.port}` : "off"}`;
  } catch (err) {
    dot.className = "dot bad";
    text.textContent = `service unreachable: ${messageOf(err)}`;
  }
}

const tokenButton = /** @type {HTMLButtonElement} */ (document.getElementById("token-button"));
tokenButton.hidden = !token();
tokenButton.addEventListener("click", () => {
  const value = prompt("API token for writes (BIOPLAN_API_TOKEN); empty to forget it:", token());
  if (value !== null) setToken(value.trim());
  tokenButton.hidden = !token();
});
document.addEventListener("bioplan:unauthorized", () => {
  tokenButton.hidden = false;
});

window.addEventListener("hashchange", route);
if (!location.hash) history.replaceState(null, "", "#/recordings");
route();
status();
setInterval(status, 15000);
document.addEventListener("bioplan:jobs", (e) => {
  active = e.detail.active;
  status();
});
