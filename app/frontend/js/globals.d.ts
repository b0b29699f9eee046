// Globals the dashboard's scripts use that no module exports, for `tsc --checkJs` (make lint).
// Only what the page calls is declared: a wrong name or argument count is then an error.

/** Plotly.js, loaded on first use from /api/viewer/assets/plotly.min.js (plots.js `plotly()`). */
interface PlotlyStatic {
  /** Draws or updates the plot in `div`, reusing what has not changed. */
  react(div: HTMLElement, data: object[], layout?: object, config?: object): Promise<PlotlyElement>;
  /** Removes the plot and its listeners from `div`. */
  purge(div: HTMLElement): void;
}

/** A div Plotly has drawn into: it gains Plotly's event methods. */
interface PlotlyElement extends HTMLElement {
  on(event: string, handler: (event: any) => void): void;
}

interface Window {
  Plotly?: PlotlyStatic;
}

/** The dashboard's own events on `document`. */
interface DocumentEventMap {
  /** The job drawer's count of queued or running jobs (jobs_drawer.js). */
  "bioplan:jobs": CustomEvent<{ active: number }>;
  /** A request was refused for want of the API token (api.js). */
  "bioplan:unauthorized": CustomEvent;
}
