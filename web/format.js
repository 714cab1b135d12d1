// How jobs, times and counts are written on the page.

export const PHASES = {
  photon_trace: "tracing photons", build_maps: "building photon maps",
  precompute: "precomputing irradiance", render: "camera pass", passes: "progressive passes",
};

export function fmtSeconds(s) {
  if (s == null || !isFinite(s)) return "-";
  if (s < 1) return `${Math.round(s * 1000)} ms`;
  if (s < 90) return `${s.toFixed(s < 10 ? 1 : 0)} s`;
  if (s < 5400) return `${Math.round(s / 60)} min`;
  return `${(s / 3600).toFixed(1)} h`;
}

export function fmtCount(n) {
  if (n == null) return "-";
  if (n >= 1e6) return `${+(n / 1e6).toFixed(2)}M`;
  if (n >= 1e3) return `${+(n / 1e3).toFixed(1)}k`;
  return String(n);
}

export function fmtTime(t) {
  return t ? new Date(t * 1000).toLocaleString() : "-";
}

export function integratorOf(job) {
  return (job.params && job.params.integrator) || "auto";
}

/// The parameters that matter most for what a job costs and shows.
export function keyParams(job) {
  const p = job.params || {};
  const s = (job.stats && job.stats.params) || {};
  const w = p.width || s.width, h = p.height || s.height;
  const out = [];
  if (w && h) out.push(`${w}x${h}`);
  // A job's params are its stored spec: the fields its integrator reads.
  if (p.photons != null) out.push(`${fmtCount(p.photons)} photons`);
  if (p.k != null) out.push(`k ${p.k}`);
  if (p.iterations != null) out.push(`${p.iterations} passes`);
  else if (p.time_limit != null) out.push(`passes for ${fmtSeconds(p.time_limit)}`);
  if (p.spp != null) out.push(`${p.spp} spp`);
  return out.join(", ");
}

export function sceneOf(job) {
  return job.scene || "(uploaded scene)";
}

export function duration(job) {
  if (job.started && job.finished) return job.finished - job.started;
  if (job.started) return Date.now() / 1000 - job.started;
  return null;
}

export function isFinal(status) {
  return status === "done" || status === "failed" || status === "cancelled";
}
