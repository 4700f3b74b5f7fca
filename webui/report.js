// Run report: the plots of seed 000 figs. 9–10 (speed and reference, speed error, traction effort)
// from the vehicle's 1 Hz telemetry history.
import { api, errorText, kmh } from "./api.js";
import { draw, line } from "./charts.js";

const $ = (selector) => document.querySelector(selector);
const HISTORY_LIMIT = 20000;

export class ReportView {
  constructor() {
    $("#report-refresh").addEventListener("click", () => this.load());
  }

  show(vehicleId) {
    this.vehicleId = vehicleId;
    $("#report-vehicle").textContent = vehicleId;
    this.load();
  }

  hide() {}

  async load() {
    const answer = await api(`/vehicles/${encodeURIComponent(this.vehicleId)}/telemetry?limit=${HISTORY_LIMIT}`);
    const message = $("#report-message");
    if (!answer.ok) { message.textContent = `Telemetry history: ${errorText(answer)}`; return; }
    const rows = answer.data;
    message.textContent = `${rows.length} samples at 1 Hz`;
    message.dataset.samples = String(rows.length);
    const time = rows.map((r) => r.sim_time_s);
    const speed = rows.map((r) => kmh(r.speed_mps));
    const reference = rows.map((r) => kmh(r.reference_speed_mps));
    const error = rows.map((r) => (r.reference_speed_mps === null ? null : kmh(r.speed_mps - r.reference_speed_mps)));
    const traction = rows.map((r) => r.traction_force_n / 1000);
    // Shade the stretches in AD, as the seed's figures mark the RD → AD switch.
    const shapes = [];
    let startS = null;
    rows.forEach((r, i) => {
      const ad = r.sc_state === "AD";
      if (ad && startS === null) startS = r.sim_time_s;
      if ((!ad || i === rows.length - 1) && startS !== null) {
        shapes.push({ type: "rect", xref: "x", yref: "paper", x0: startS, x1: r.sim_time_s, y0: 0, y1: 1, fillcolor: "#e3f2fd", line: { width: 0 }, layer: "below" });
        startS = null;
      }
    });
    const xaxis = { title: { text: "sim time [s]" } };
    draw($("#report-speed"), [
      line("speed", time, speed, { line: { color: "#1565c0" } }),
      line("reference", time, reference, { line: { color: "#2e7d32", dash: "dash" } }),
      line("permitted", time, rows.map((r) => kmh(r.permitted_speed_mps)), { line: { color: "#f9a825", width: 1 } }),
    ], { xaxis, yaxis: { title: { text: "km/h" }, rangemode: "tozero" }, shapes });
    draw($("#report-error"), [line("speed − reference", time, error, { line: { color: "#6a1b9a" } })],
      { xaxis, yaxis: { title: { text: "km/h" } }, shapes });
    draw($("#report-traction"), [line("traction effort", time, traction, { line: { color: "#c62828" } })],
      { xaxis, yaxis: { title: { text: "kN" } }, shapes });
  }
}
