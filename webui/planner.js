// Journey planner: pick any stored line, list timing points, validate and save through the
// journeys API; see the line's map (its geodetic polyline, stopping points and the start), its
// speed and gradient profiles (static line speed, MRSP), the journey's cap and its stops.
import { api, element, errorText, fixed, kmh } from "./api.js";
import { draw, line } from "./charts.js";
import { LineMap } from "./map.js";

const $ = (selector) => document.querySelector(selector);
const KINDS = ["stopping", "passing", "skip"];

export class PlannerView {
  constructor() {
    this.lines = [];
    this.line = null;
    this.map = new LineMap($("#planner-map"));
    $("#planner-start").addEventListener("change", () => this.drawProfile());
    $("#planner-line").addEventListener("change", () => this.pickLine($("#planner-line").value));
    $("#planner-add-tp").addEventListener("click", () => this.addTimingPoint());
    $("#planner-validate").addEventListener("click", () => this.validate());
    $("#planner-save").addEventListener("click", () => this.save());
    $("#planner-from-vehicle").addEventListener("click", () => this.startAtVehicle());
    $("#planner-max").addEventListener("change", () => this.drawProfile());
  }

  async show() {
    const [lines, vehicles] = await Promise.all([api("/lines"), api("/vehicles")]);
    this.lines = lines.ok ? lines.data : [];
    const select = $("#planner-line");
    const previous = select.value;
    select.replaceChildren(...this.lines.map((l) => element("option", { value: l.id, text: `${l.name} (${l.id})` })));
    if (previous) select.value = previous;
    const vehicleSelect = $("#planner-vehicle");
    vehicleSelect.replaceChildren(...(vehicles.ok ? vehicles.data : []).filter((v) => v.status)
      .map((v) => element("option", { value: v.id, text: `${v.id} at ${fixed(v.status.position_m)} m` })));
    if (select.value) await this.pickLine(select.value);
  }

  hide() {}

  async pickLine(lineId) {
    // Only the line picked last is drawn: an earlier pick's answers may come after it.
    this.picked = lineId;
    const [document_, profile] = await Promise.all([
      api(`/lines/${encodeURIComponent(lineId)}`),
      api(`/lines/${encodeURIComponent(lineId)}/profile`),
    ]);
    if (this.picked !== lineId) return;
    if (!document_.ok) { this.report(false, errorText(document_)); return; }
    this.line = document_.data;
    this.profile = profile.ok ? profile.data : null;
    this.map.setLine(this.line);
    for (const row of $("#planner-tps tbody").children) this.fillStops(row.querySelector("[data-tp=stop]"));
    this.drawProfile();
  }

  async startAtVehicle() {
    const vehicleId = $("#planner-vehicle").value;
    if (!vehicleId) return;
    const answer = await api(`/vehicles/${encodeURIComponent(vehicleId)}`);
    if (!answer.ok || !answer.data.status) { this.report(false, `${vehicleId}: no live status`); return; }
    const status = answer.data.status;
    if (status.line_id !== $("#planner-line").value) {
      $("#planner-line").value = status.line_id;
      await this.pickLine(status.line_id);
    }
    const length = this.line ? this.line.length_m : Infinity;
    const position = this.line && this.line.ring ? ((status.position_m % length) + length) % length : status.position_m;
    $("#planner-start").value = position.toFixed(1);
    this.drawProfile();
  }

  fillStops(select) {
    const chosen = select.value;
    select.replaceChildren(element("option", { value: "", text: "(chainage)" }),
      ...(this.line ? this.line.stopping_points : []).map((s) => element("option", { value: s.id, text: `${s.name} (${s.position_m} m)` })));
    select.value = chosen;
  }

  addTimingPoint() {
    const body = $("#planner-tps tbody");
    const index = body.children.length + 1;
    const stop = element("select", { dataset: { tp: "stop" } });
    this.fillStops(stop);
    const kind = element("select", { dataset: { tp: "kind" } }, ...KINDS.map((k) => element("option", { value: k, text: k })));
    const row = element("tr", { dataset: { timingPoint: String(index) } },
      element("td", {}, element("input", { dataset: { tp: "id" }, value: `tp${index}`, size: "8" })),
      element("td", {}, stop),
      element("td", {}, element("input", { dataset: { tp: "position" }, type: "number", min: "0", step: "0.1", size: "8" })),
      element("td", {}, kind),
      element("td", {}, element("input", { dataset: { tp: "arrival" }, type: "number", min: "0", step: "1", value: String(index * 300), size: "6" })),
      element("td", {}, element("input", { dataset: { tp: "departure" }, type: "number", min: "0", step: "1", size: "6" })),
      element("td", {}, element("button", { type: "button", text: "Remove", onclick: () => row.remove() })));
    body.append(row);
    return row;
  }

  journey() {
    const rows = [...$("#planner-tps tbody").children];
    const timingPoints = rows.map((row, i) => {
      const value = (name) => row.querySelector(`[data-tp=${name}]`).value;
      const tp = { id: value("id"), kind: value("kind"), arrival_time_s: Number(value("arrival")) };
      if (value("stop")) tp.stopping_point_id = value("stop");
      else tp.position_m = Number(value("position"));
      if (value("departure") !== "") tp.departure_time_s = Number(value("departure"));
      if (i === rows.length - 1) tp.end_of_journey = true;
      return tp;
    });
    const journey = {
      id: $("#planner-id").value,
      line_id: $("#planner-line").value,
      start_position_m: Number($("#planner-start").value),
      timing_points: timingPoints,
    };
    if ($("#planner-max").value !== "") journey.max_speed_mps = Number($("#planner-max").value) / 3.6;
    return journey;
  }

  report(ok, text) {
    const node = $("#planner-result");
    node.dataset.ok = String(ok);
    node.textContent = text;
  }

  showLegs(check) {
    const table = $("#planner-legs");
    table.hidden = !check || !check.legs;
    if (!check || !check.legs) return;
    table.tBodies[0].replaceChildren(...check.legs.map((leg) => element("tr", { dataset: { leg: String(leg.index) } },
      element("td", { text: `${leg.from_id} → ${leg.to_id}` }),
      element("td", { class: "num", text: fixed(leg.distance_m, 0) }),
      element("td", { class: "num", text: fixed(leg.scheduled_s, 0) }),
      element("td", { class: "num", text: fixed(leg.minimum_s, 0) }),
      element("td", { class: "num", text: fixed(leg.shortfall_s, 0) }))));
  }

  async validate() {
    const answer = await api("/journeys/validate", { method: "POST", body: this.journey() });
    if (!answer.ok) { this.report(false, errorText(answer)); this.showLegs(null); return; }
    const check = answer.data;
    this.report(check.valid, check.valid ? "valid" : `not valid: ${check.problems.join("; ")}`);
    this.showLegs(check);
    this.drawProfile();
  }

  async save() {
    const answer = await api("/journeys", { method: "POST", body: this.journey() });
    if (answer.ok) {
      this.report(true, `saved ${answer.data.journey.id} version ${answer.data.version}`);
      return;
    }
    const detail = answer.data && answer.data.detail;
    this.report(false, detail && detail.problems ? `not saved: ${detail.problems.join("; ")}` : errorText(answer));
    if (detail && detail.legs) this.showLegs(detail);
  }

  drawProfile() {
    if (!this.line) return;
    const traces = [];
    if (this.profile) {
      traces.push(line("line speed", this.profile.chainage_m, this.profile.speed_limit_mps.map(kmh), { line: { color: "#9e9e9e" } }));
      traces.push(line("MRSP", this.profile.chainage_m, this.profile.mrsp_mps.map(kmh), { line: { color: "#f9a825" } }));
      traces.push(line("gradient [‰]", this.profile.chainage_m, this.profile.gradient_permille, { yaxis: "y2", line: { color: "#8d6e63", width: 1 } }));
    }
    const cap = Number($("#planner-max").value);
    if (cap > 0) traces.push(line("journey cap", [0, this.line.length_m], [cap, cap], { line: { color: "#2e7d32", dash: "dash" } }));
    const stops = this.line.stopping_points;
    traces.push({ type: "scatter", mode: "markers+text", name: "stopping points", x: stops.map((s) => s.position_m),
      y: stops.map(() => 0), text: stops.map((s) => s.name), textposition: "top center", marker: { color: "#1565c0", size: 9 } });
    const start = Number($("#planner-start").value);
    this.map.setStart(start);
    traces.push({ type: "scatter", mode: "markers", name: "start", x: [start], y: [0], marker: { color: "#c62828", symbol: "triangle-right", size: 12 } });
    draw($("#planner-chart"), traces, {
      xaxis: { title: { text: "chainage [m]" } },
      yaxis: { title: { text: "km/h" }, rangemode: "tozero" },
      yaxis2: { title: { text: "‰" }, overlaying: "y", side: "right", showgrid: false },
    });
  }
}
