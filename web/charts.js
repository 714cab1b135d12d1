// Charts of how a progressive render converged, drawn as inline SVG (no library).

/// A log-log line chart of `series` ([{ name, points: [[x, y]...] }]) as an SVG figure.
function logChart(title, xLabel, series, id) {
  const W = 360, H = 220, L = 48, R = 10, T = 10, B = 34;
  series = series.filter((s) => s.points.some(([x, y]) => x > 0 && y > 0));
  const all = series.flatMap((s) => s.points).filter(([x, y]) => x > 0 && y > 0);
  const fig = document.createElement("figure");
  fig.className = "chart";
  if (id) fig.id = id;
  const cap = document.createElement("figcaption");
  cap.textContent = title;
  if (all.length < 2) return null;
  const lx = all.map(([x]) => Math.log10(x)), ly = all.map(([, y]) => Math.log10(y));
  const [x0, x1] = [Math.min(...lx), Math.max(...lx) || 1];
  let [y0, y1] = [Math.min(...ly), Math.max(...ly)];
  if (y1 - y0 < 1e-9) { y0 -= 0.5; y1 += 0.5; }
  const px = (x) => L + ((Math.log10(x) - x0) / (x1 - x0 || 1)) * (W - L - R);
  const py = (y) => T + (1 - (Math.log10(y) - y0) / (y1 - y0)) * (H - T - B);
  const NS = "http://www.w3.org/2000/svg";
  const svg = document.createElementNS(NS, "svg");
  svg.setAttribute("viewBox", `0 0 ${W} ${H}`);
  svg.setAttribute("role", "img");
  svg.setAttribute("aria-label", `${title} (log-log), ${series.map((s) => s.name).join(", ")}`);
  const add = (tag, attrs, text) => {
    const el = document.createElementNS(NS, tag);
    for (const [k, v] of Object.entries(attrs)) el.setAttribute(k, v);
    if (text != null) el.textContent = text;
    svg.appendChild(el);
    return el;
  };
  add("rect", { x: L, y: T, width: W - L - R, height: H - T - B, class: "plot" });
  const fmt = (v) => (v >= 0.01 && v < 1000 ? +v.toPrecision(2) : v.toExponential(0));
  add("text", { x: L, y: H - 18, class: "tick" }, fmt(10 ** x0));
  add("text", { x: W - R, y: H - 18, class: "tick end" }, fmt(10 ** x1));
  add("text", { x: L - 4, y: T + 10, class: "tick end" }, fmt(10 ** y1));
  add("text", { x: L - 4, y: H - B, class: "tick end" }, fmt(10 ** y0));
  add("text", { x: (L + W - R) / 2, y: H - 4, class: "tick mid" }, xLabel);
  series.forEach((s, i) => {
    const pts = s.points.filter(([x, y]) => x > 0 && y > 0);
    add("polyline", {
      class: `line line${i}`, "data-series": s.name,
      "data-points": pts.length,
      points: pts.map(([x, y]) => `${px(x).toFixed(1)},${py(y).toFixed(1)}`).join(" "),
    });
    add("text", { x: W - R - 4, y: T + 14 + 14 * i, class: `tick end label${i}` }, s.name);
  });
  fig.append(svg, cap);
  return fig;
}

/// How a progressive render converged: the estimate radius shrinking pass by pass, the time
/// per pass (the error against a reference: see `accuracy`).
export function convergence(ppm) {
  const h = (ppm && ppm.history) || [];
  if (h.length < 2) return null;
  const series = [
    { name: "global radius", points: h.map((p) => [p.pass, p.radius_global]) },
    { name: "caustic radius", points: h.map((p) => [p.pass, p.radius_caustic]) },
  ];
  const box = document.createElement("div");
  box.className = "charts";
  const a = logChart("Estimate radius per pass (scene units)", "pass", series);
  const b = logChart("Time: seconds elapsed after each pass", "pass",
    [{ name: "elapsed", points: h.map((p) => [p.pass, p.elapsed]) }]);
  for (const f of [a, b]) if (f) box.appendChild(f);
  return box;
}

/// How the error against the reference job fell: relmse against elapsed seconds, and
/// relmse and block_err per pass (log-log), for a progressive render that had a reference.
export function accuracy(ppm) {
  const h = ((ppm && ppm.history) || []).filter((p) => p.error);
  if (h.length < 2) return null;
  const box = document.createElement("div");
  box.className = "charts";
  const a = logChart("Error against the reference vs time (seconds)", "seconds",
    [{ name: "relmse", points: h.map((p) => [p.elapsed, p.error.relmse]) }], "chart-error-time");
  const b = logChart("Error against the reference per pass", "pass", [
    { name: "relmse", points: h.map((p) => [p.pass, p.error.relmse]) },
    { name: "block_err", points: h.map((p) => [p.pass, p.error.block_err]) },
  ], "chart-error-pass");
  for (const f of [a, b]) if (f) box.appendChild(f);
  return box.children.length ? box : null;
}
