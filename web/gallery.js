// The gallery: every job this user may see as a card, newest first, refreshed by polling
// GET /api/jobs; a card's thumbnail is refetched only when its job's status or progress moved.

import { apiJson, loadImage } from "./api.js";
import { duration, fmtSeconds, fmtTime, integratorOf, keyParams, sceneOf } from "./format.js";
import { $, state } from "./state.js";
import { fillReferences, updateEstimate } from "./submit.js";

export function startGallery() {
  stopGallery();
  const tick = async () => {
    await refreshGallery();
    // Faster while something renders; the list is served from memory.
    const busy = state.jobs.some((j) => j.status === "queued" || j.status === "running");
    state.galleryTimer = setTimeout(tick, busy ? 700 : 2500);
  };
  tick();
}

export function stopGallery() {
  clearTimeout(state.galleryTimer);
  state.galleryTimer = null;
}

/// Fetch the job list into `state.jobs` and redraw the cards.
export async function refreshGallery() {
  let jobs;
  try {
    jobs = (await apiJson("/api/jobs")).jobs;
  } catch (_) {
    return;
  }
  // Ids are random: newest first by creation time.
  jobs.sort((a, b) => b.created - a.created || b.id - a.id);
  state.jobs = jobs;
  renderGallery();
  fillReferences();
  updateEstimate();
}

function renderGallery() {
  const list = $("gallery");
  const existing = new Map([...list.children].map((li) => [Number(li.dataset.jobId), li]));
  const seen = new Set();
  for (const job of state.jobs) {
    let li = existing.get(job.id);
    if (!li) li = makeCard(job);
    updateCard(li, job);
    list.appendChild(li); // moves it into newest-first order
    seen.add(job.id);
  }
  for (const [id, li] of existing) {
    if (!seen.has(id)) {
      li.remove();
      const t = state.thumbs.get(id);
      if (t) URL.revokeObjectURL(t.url);
      state.thumbs.delete(id);
    }
  }
  $("gallery-empty").hidden = state.jobs.length > 0;
  list.dataset.refreshes = String(Number(list.dataset.refreshes) + 1);
}

function makeCard(job) {
  const li = document.createElement("li");
  li.className = "card";
  li.dataset.jobId = job.id;
  li.innerHTML = `
    <a class="thumb-link"><img class="thumb" alt=""><span class="nothumb">no image yet</span></a>
    <div class="card-body">
      <h3><a class="title"></a></h3>
      <p class="meta params"></p>
      <p class="meta owner"></p>
      <p class="meta times"></p>
      <p class="status-line"><span class="status"></span>
        <progress class="mini" max="1" value="0" aria-hidden="true"></progress></p>
    </div>`;
  return li;
}

function updateCard(li, job) {
  const href = `#/job/${job.id}`;
  const label = `Job ${job.id}: ${sceneOf(job)}, ${integratorOf(job)}`;
  li.dataset.owner = job.owner || "";
  li.dataset.public = String(job.public);
  li.dataset.status = job.status;
  const link = li.querySelector(".thumb-link");
  link.href = href;
  link.tabIndex = -1; // the title link is the keyboard stop
  link.setAttribute("aria-hidden", "true");
  const title = li.querySelector(".title");
  title.href = href;
  title.textContent = `#${job.id} ${sceneOf(job)}`;
  li.querySelector(".params").textContent = `${integratorOf(job)}: ${keyParams(job)}`;
  li.querySelector(".owner").textContent =
    `${job.mine ? "yours" : `by ${job.owner}`} · ${job.public ? "public" : "private"}`;
  const d = duration(job);
  li.querySelector(".times").textContent =
    `submitted ${fmtTime(job.created)}${d != null ? ` · ${fmtSeconds(d)}` : ""}`;
  const status = li.querySelector(".status");
  status.textContent = job.status === "running" ? `running ${Math.round(job.progress * 100)}%`
    : job.status === "queued" && job.queue_position != null ? `queued (#${job.queue_position + 1})`
    : job.status;
  status.className = `status status-${job.status}`;
  const mini = li.querySelector(".mini");
  mini.value = job.progress || 0;
  mini.hidden = job.status !== "running";
  const img = li.querySelector(".thumb");
  img.alt = `Thumbnail of ${label}`;
  refreshThumb(li, job);
}

/// Fetch a card's image when it may have changed (a running ppm job publishes previews).
async function refreshThumb(li, job) {
  if (job.status === "queued") return;
  const key = `${job.status}:${Math.floor((job.progress || 0) * 20)}`;
  const have = state.thumbs.get(job.id);
  if (have && have.key === key) return;
  state.thumbs.set(job.id, { key, url: have ? have.url : "" });
  const img = li.querySelector(".thumb");
  const ok = await loadImage(img, `/api/jobs/${job.id}/image.png`);
  if (ok) {
    li.classList.add("has-thumb");
    state.thumbs.set(job.id, { key, url: img.dataset.objectUrl });
  }
}

/// Forget every card and thumbnail (on signing out).
export function clearGallery() {
  for (const t of state.thumbs.values()) URL.revokeObjectURL(t.url);
  state.thumbs.clear();
  $("gallery").replaceChildren();
}
