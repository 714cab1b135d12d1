// photonbox gallery: plain JavaScript in native ES modules, no build step. This module signs
// in and out, routes `#/`, `#/job/ID` and `#/compare/A/B` to their views, and wires the page.
// The others, by concern: api.js (token, fetch, SSE over fetch), state.js (shared state),
// format.js, gallery.js, submit.js (form, presets, estimate, field errors), job.js (job page),
// charts.js (convergence charts), compare.js.

import { TOKEN_KEY, apiJson, onUnauthorized, specDefaults, takeTokenFromUrl } from "./api.js";
import { initCompare, openCompare } from "./compare.js";
import { clearGallery, startGallery, stopGallery } from "./gallery.js";
import { initJob, openJob } from "./job.js";
import { $, showView, state } from "./state.js";
import { fillIntegrators, fillScenes, initSubmit, onIntegratorChange } from "./submit.js";

function signOut(message) {
  localStorage.removeItem(TOKEN_KEY);
  state.token = null;
  state.me = null;
  state.jobs = [];
  clearGallery();
  $("me").textContent = "";
  $("sign-out").hidden = true;
  $("signin-error").textContent = message || "";
  showView("signin");
}

async function signIn() {
  state.token = localStorage.getItem(TOKEN_KEY);
  if (!state.token) {
    showView("signin");
    return;
  }
  try {
    state.me = await apiJson("/api/me");
  } catch (e) {
    if (e.status !== 401) signOut(`Could not reach the server: ${e.message}`);
    return;
  }
  $("me").textContent = `Signed in as ${state.me.name}${state.me.admin ? " (admin)" : ""}`;
  $("sign-out").hidden = false;
  try {
    state.scenes = (await apiJson("/api/scenes")).scenes;
  } catch (_) {
    state.scenes = [];
  }
  try {
    state.defaults = await specDefaults();
  } catch (_) {
    state.defaults = null; // the fields stay empty: the server applies its defaults
  }
  fillIntegrators();
  onIntegratorChange();
  fillScenes();
  route();
}

/// `#/` gallery, `#/job/ID`, `#/compare/A/B`.
function route() {
  if (!state.token || !state.me) return;
  if (state.view) state.view.abort();
  state.view = new AbortController();
  const parts = location.hash.replace(/^#\/?/, "").split("/").filter(Boolean);
  if (parts[0] === "job" && parts[1]) {
    stopGallery();
    openJob(Number(parts[1]), state.view.signal);
  } else if (parts[0] === "compare") {
    stopGallery();
    openCompare(Number(parts[1]) || null, Number(parts[2]) || null, state.view.signal);
  } else {
    showView("gallery");
    document.title = "photonbox: renders";
    startGallery();
  }
}

function init() {
  takeTokenFromUrl();
  onUnauthorized(() => signOut("That token was not accepted: sign in again."));
  $("signin-form").addEventListener("submit", (ev) => {
    ev.preventDefault();
    const t = $("signin-token").value.trim();
    if (!t) return;
    localStorage.setItem(TOKEN_KEY, t);
    $("signin-token").value = "";
    signIn();
  });
  $("sign-out").addEventListener("click", () => signOut("Signed out."));
  initSubmit();
  initJob();
  initCompare();
  window.addEventListener("hashchange", route);
  onIntegratorChange();
  signIn();
}

init();
