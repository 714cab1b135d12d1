// What the views share: the signed-in user, the last job list, caches, the open view.

export const $ = (id) => document.getElementById(id);

export const state = {
  token: null,
  me: null,
  jobs: [],            // the last GET /api/jobs, newest first
  scenes: [],
  defaults: null,      // each integrator's defaults: the API document's Params x-defaults
  sceneSizes: new Map(), // built-in scene name -> [width, height]
  thumbs: new Map(),   // job id -> { key, url }
  galleryTimer: null,
  view: null,          // the AbortController of the open job or compare view
  currentJob: null,    // the job the job page shows
};

/// Show the section `view-NAME` and hide the others.
export function showView(name) {
  for (const v of document.querySelectorAll(".view")) v.hidden = v.id !== `view-${name}`;
}
