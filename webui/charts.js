// Thin wrappers over Plotly (served by trackside from the plotly wheel, loaded as a global).
const layoutBase = {
  margin: { l: 55, r: 15, t: 30, b: 40 },
  legend: { orientation: "h", y: -0.25 },
  paper_bgcolor: "#fff",
  plot_bgcolor: "#fff",
  font: { size: 11 },
};

export function available() { return typeof window.Plotly !== "undefined"; }

export function draw(target, traces, layout) {
  if (!available()) {
    target.textContent = "Charting library not loaded (/vendor/plotly.min.js).";
    return;
  }
  // The container's own width: a chart first drawn while its view was hidden would keep 700 px.
  const width = target.clientWidth || undefined;
  window.Plotly.react(target, traces, { ...layoutBase, width, ...layout }, { responsive: true, displaylogo: false });
}

export function line(name, x, y, extra = {}) {
  return { type: "scatter", mode: "lines", name, x, y, ...extra };
}
