// Driver console for one vehicle: hold it, watch it live, command it, answer its Vital Control.
import { api, element, errorText, fixed, kmh, kwhText, leaseEnd, openSocket, socText } from "./api.js";
import { draw, line } from "./charts.js";
import { TrackStrip } from "./track.js";

const $ = (selector) => document.querySelector(selector);
const MAX_SAMPLES = 4000;
const REDRAW_MS = 500;
const POLL_MS = 500;
const EVENT_POLL_MS = 1000;
const EVENT_POLL_LIMIT = 50;
// The kind of each VC request in the path of its one confirmation route (/confirmations/{kind}).
const confirmRoutes = {
  vigilance: "vigilance-ack",
  eb_rearm: "eb-rearm",
  etcs_isolation: "etcs-isolation",
  etcs_insertion: "etcs-insertion",
};
const requestLabels = {
  vigilance: "Vigilance",
  eb_rearm: "EB rearm",
  etcs_isolation: "ETCS isolation",
  etcs_insertion: "ETCS insertion",
};

function setField(name, text, alarm = false) {
  const node = document.querySelector(`#driver-panel [data-field="${name}"]`);
  node.textContent = text;
  node.dataset.alarm = String(alarm);
}

const speedText = (mps) => (mps === null || mps === undefined ? "–" : `${fixed(kmh(mps))} km/h`);

class Samples {
  constructor() { this.clear(); }
  clear() {
    this.time = []; this.position = []; this.speed = []; this.reference = []; this.permitted = []; this.intervention = [];
  }
  add(t, p, v, ref, perm, intv) {
    if (this.time.length && t < this.time[this.time.length - 1]) this.clear();
    this.time.push(t); this.position.push(p); this.speed.push(kmh(v));
    this.reference.push(kmh(ref)); this.permitted.push(kmh(perm)); this.intervention.push(kmh(intv));
    if (this.time.length > MAX_SAMPLES) for (const series of Object.values(this)) series.shift();
  }
}

export class DriverView {
  constructor(setConnection) {
    this.setConnection = setConnection;
    this.vehicleId = null;
    this.samples = new Samples();
    this.track = new TrackStrip($("#track-strip"));
    this.lineId = null;
    this.status = null;
    this.dirty = false;
    this.timers = [];
    this.socket = null;
    this.seenEvents = new Set();
    this.bindCommands();
  }

  bindCommands() {
    $("#select-vehicle").addEventListener("click", () => this.hold("select"));
    $("#release-vehicle").addEventListener("click", () => this.hold("release"));
    $("#send-journey").addEventListener("click", () => this.sendJourney());
    $("#engage").addEventListener("click", () => this.command("engage", {}));
    $("#disengage").addEventListener("click", () => this.command("disengage", {}));
    $("#rd-send").addEventListener("click", () =>
      this.command("rd-target-speed", { target_speed_kmh: Number($("#rd-speed").value) }));
    $("#skip-send").addEventListener("click", () =>
      this.command("skip-stop", { timing_point_id: $("#skip-tp").value }));
    $("#hold-on").addEventListener("click", () => this.command("train-hold", { hold: true }));
    $("#hold-off").addEventListener("click", () => this.command("train-hold", { hold: false }));
    $("#emergency-brake").addEventListener("click", () => this.command("emergency-brake", {}));
    $("#vigilance-ack").addEventListener("click", (event) => {
      this.confirm("vigilance", Number(event.currentTarget.dataset.number));
    });
    $("#journey-select").addEventListener("change", () => this.fillSkipStops());
    $("#journeys-reload").addEventListener("click", () => this.loadJourneys());
  }

  async show(vehicleId) {
    this.vehicleId = vehicleId;
    this.samples.clear();
    this.seenEvents.clear();
    this.lineId = null;
    $("#driver-vehicle").textContent = vehicleId;
    $("#report-link").href = `#/report/${encodeURIComponent(vehicleId)}`;
    $("#event-log tbody").replaceChildren();
    $("#driver-message").textContent = "";
    for (const slot of ["#command-answer", "#journey-answer", "#request-answer"]) $(slot).textContent = "";
    await this.loadHistory();
    const vehicle = await api(`/vehicles/${encodeURIComponent(vehicleId)}`);
    if (!vehicle.ok) {
      $("#driver-message").textContent = `Vehicle ${vehicleId}: ${errorText(vehicle)}`;
    } else {
      this.onVehicle(vehicle.data.status, vehicle.data.holder, vehicle.data.simulated_operator, vehicle.data.hold_expires_at);
    }
    this.loadJourneys();
    this.loadEvents();
    this.connect();
    this.timers.push(setInterval(() => this.redraw(), REDRAW_MS));
  }

  hide() {
    for (const timer of this.timers) { clearInterval(timer); clearTimeout(timer); }
    this.timers = [];
    if (this.socket) { this.socket.onclose = null; this.socket.close(); this.socket = null; }
  }

  path(action) { return `/vehicles/${encodeURIComponent(this.vehicleId)}/${action}`; }

  connect() {
    let opened = false;
    this.socket = openSocket(`/ws/vehicles/${encodeURIComponent(this.vehicleId)}`);
    this.socket.onopen = () => { opened = true; this.setConnection(true); };
    this.socket.onmessage = (event) => {
      const frame = JSON.parse(event.data);
      if (frame.type === "status") this.onVehicle(frame.status, frame.holder, frame.simulated_operator, frame.hold_expires_at);
      else if (frame.type === "event") this.addEvent(frame.event);
    };
    this.socket.onclose = (event) => {
      this.setConnection(false);
      this.socket = null;
      if (event.code === 1008) return;
      // A trackside without the per-vehicle stream: poll the vehicle instead.
      if (!opened) this.poll();
      else this.timers.push(setTimeout(() => this.connect(), 1000));
    };
  }

  poll() {
    this.setConnection(true);
    $("#connection").textContent = "polling";
    const tick = async () => {
      const answer = await api(`/vehicles/${encodeURIComponent(this.vehicleId)}`);
      if (answer.ok) this.onVehicle(answer.data.status, answer.data.holder, answer.data.simulated_operator, answer.data.hold_expires_at);
    };
    this.timers.push(setInterval(tick, POLL_MS));
    this.timers.push(setInterval(() => this.loadEvents(EVENT_POLL_LIMIT), EVENT_POLL_MS));
  }

  async loadJourneys() {
    const answer = await api("/journeys");
    const select = $("#journey-select");
    const chosen = select.value;
    select.replaceChildren();
    this.journeys = answer.ok ? answer.data : [];
    for (const stored of this.journeys) {
      const journey = stored.journey;
      select.append(element("option", { value: journey.id, text: `${journey.id} v${stored.version} (${journey.line_id})` }));
    }
    if ([...select.options].some((option) => option.value === chosen)) select.value = chosen;
    this.fillSkipStops();
  }

  fillSkipStops() {
    const stored = (this.journeys || []).find((j) => j.journey.id === $("#journey-select").value);
    const select = $("#skip-tp");
    select.replaceChildren();
    for (const tp of stored ? stored.journey.timing_points : []) select.append(element("option", { value: tp.id, text: tp.id }));
  }

  async loadHistory() {
    const answer = await api(`${this.path("telemetry")}?limit=3600`);
    if (!answer.ok || !Array.isArray(answer.data)) return;
    for (const row of answer.data) {
      this.samples.add(row.sim_time_s, row.position_m, row.speed_mps, row.reference_speed_mps,
        row.permitted_speed_mps, row.intervention_speed_mps);
    }
    this.dirty = true;
  }

  async loadEvents(limit = 200) {
    const answer = await api(`${this.path("events")}?limit=${limit}`);
    if (answer.ok && Array.isArray(answer.data)) for (const event of answer.data) this.addEvent(event);
  }

  async loadLine(lineId) {
    this.lineId = lineId;
    const answer = await api(`/lines/${encodeURIComponent(lineId)}`);
    if (answer.ok) {
      this.track.setLine(answer.data);
      if (this.status) this.track.setTrain(this.status.position_m);
    }
  }

  addEvent(event) {
    const key = event.seq !== undefined && event.seq !== null ? `s${event.seq}` : `${event.sim_time_s}/${event.code}`;
    if (this.seenEvents.has(key)) return;
    this.seenEvents.add(key);
    const row = element("tr", { dataset: { code: event.code, severity: event.severity } },
      element("td", { class: "num", text: fixed(event.sim_time_s) }),
      element("td", { text: event.severity }),
      element("td", { text: event.code }),
      element("td", { text: event.text }));
    const body = $("#event-log tbody");
    body.prepend(row);
    while (body.children.length > 300) body.lastChild.remove();
  }

  showHolder(holder, expiresAt) {
    const badge = $("#driver-holder");
    badge.textContent = holder ? `held by ${holder}` : "not held";
    badge.dataset.holder = holder || "";
    badge.className = "badge " + (holder ? "on" : "neutral");
    const lease = $("#driver-lease");
    lease.textContent = holder && expiresAt ? `lease to ${leaseEnd(expiresAt)}` : "";
    lease.dataset.expiresAt = (holder && expiresAt) || "";
  }

  onVehicle(status, holder, simulatedOperator, holdExpiresAt) {
    this.showHolder(holder, holdExpiresAt);
    const operator = $("#simulated-operator");
    if (simulatedOperator === true || simulatedOperator === false) {
      operator.dataset.simulated = String(simulatedOperator);
      operator.textContent = simulatedOperator ? "SIMULATED OPERATOR answers the VC" : "operator: a person";
      operator.className = "badge " + (simulatedOperator ? "warn" : "on");
    }
    if (!status) { setField("speed", "vehicle not alive", true); return; }
    this.status = status;
    if (status.line_id !== this.lineId) this.loadLine(status.line_id);
    this.track.setTrain(status.position_m);
    this.samples.add(status.sim_time_s, status.position_m, status.speed_mps, status.reference_speed_mps,
      status.permitted_speed_mps, status.intervention_speed_mps);
    this.dirty = true;
    if (this.samples.time.length === 1) this.redraw();
    this.showStatus(status);
    this.showVitalControl(status);
  }

  showStatus(s) {
    setField("speed", speedText(s.speed_mps));
    setField("position", `${fixed(s.position_m)} m`);
    setField("reference", speedText(s.reference_speed_mps));
    setField("permitted", speedText(s.permitted_speed_mps));
    setField("intervention", speedText(s.intervention_speed_mps));
    setField("etcs-mode", s.etcs_mode);
    setField("supervision", s.supervision_status, s.supervision_status !== "normal");
    setField("ato-state", s.ato_state);
    setField("sc-state", s.sc_state);
    setField("journey", s.journey_id || "–");
    setField("next-tp", s.next_timing_point_id || "–");
    setField("train-hold", s.train_hold ? "held" : "no", Boolean(s.train_hold));
    this.showEnergy(s.energy);
    setField("sim-time", `${fixed(s.sim_time_s)} s`);
  }

  showEnergy(energy) {
    const soc = socText(energy);
    setField("soc", soc === "–" ? soc : `${soc} %`);
    const toGo = kwhText(energy ? energy.energy_to_go_j : null);
    setField("energy-to-go", toGo === "–" ? toGo : `${toGo} kWh`);
    const margin = kwhText(energy ? energy.margin_j : null);
    let text = margin === "–" ? margin : `${margin} kWh`;
    if (energy && energy.short) text += " SHORT: do not engage";
    else if (energy && energy.slowed) text += " (plan slowed within the windows)";
    setField("energy-margin", text, Boolean(energy && energy.short));
  }

  showVitalControl(s) {
    const vc = s.vital_control;
    if (!vc) {
      for (const name of ["vc-eb", "vc-decay", "vc-conditions", "vc-supervision", "vc-brake", "vc-etcs", "vc-standstill"]) setField(name, "–");
      this.showRequests([], s.sim_time_s);
      return;
    }
    setField("vc-eb", vc.eb_commanded ? "APPLIED" : "released", vc.eb_commanded);
    setField("vc-decay", vc.system_decay ? `YES (${vc.decay_reasons.join(", ")})` : "no", vc.system_decay);
    setField("vc-conditions", vc.eb_conditions.length ? vc.eb_conditions.join(", ") : "none", vc.eb_conditions.length > 0);
    setField("vc-supervision", vc.supervision_state);
    setField("vc-brake", vc.brake_state);
    setField("vc-etcs", vc.etcs_isolated ? `${vc.etcs_state} (isolated)` : vc.etcs_state);
    setField("vc-standstill", vc.standstill ? "yes" : "no");
    this.showRequests(vc.operator_requests || [], s.sim_time_s);
  }

  showRequests(requests, nowS) {
    const list = $("#operator-requests");
    list.replaceChildren();
    const pending = requests.filter((r) => !r.confirmed);
    if (!pending.length) list.append(element("li", { class: "muted", text: "none" }));
    for (const request of pending) {
      const left = request.deadline_s === null || request.deadline_s === undefined ? null : request.deadline_s - nowS;
      const button = element("button", {
        dataset: { confirm: request.kind, number: String(request.number) },
        text: "Confirm",
        onclick: () => this.confirm(request.kind, request.number),
      });
      list.append(element("li", { dataset: { request: request.kind } },
        element("span", { text: `${requestLabels[request.kind] || request.kind} #${request.number}` }),
        element("span", { class: "muted", text: left === null ? "no deadline" : `${fixed(Math.max(left, 0))} s left` }),
        button));
    }
    const vigilance = pending.find((r) => r.kind === "vigilance");
    const prompt = $("#vigilance-prompt");
    prompt.hidden = !vigilance;
    if (vigilance) {
      const left = vigilance.deadline_s === null ? null : Math.max(vigilance.deadline_s - nowS, 0);
      $("#vigilance-countdown").textContent = fixed(left);
      $("#vigilance-ack").dataset.number = String(vigilance.number);
    }
  }

  redraw() {
    if (!this.dirty) return;
    this.dirty = false;
    // Copies: Plotly.react redraws only traces whose arrays are new objects.
    const s = Object.fromEntries(Object.entries(this.samples).map(([name, values]) => [name, values.slice()]));
    draw($("#chart-time"), [
      line("speed", s.time, s.speed, { line: { color: "#1565c0" } }),
      line("reference (ODP)", s.time, s.reference, { line: { color: "#2e7d32", dash: "dash" } }),
      line("permitted", s.time, s.permitted, { line: { color: "#f9a825" } }),
      line("intervention", s.time, s.intervention, { line: { color: "#c62828" } }),
    ], { xaxis: { title: { text: "sim time [s]" } }, yaxis: { title: { text: "km/h" }, rangemode: "tozero" } });
    draw($("#chart-position"), [
      line("speed", s.position, s.speed, { line: { color: "#1565c0" } }),
      line("reference (ODP)", s.position, s.reference, { line: { color: "#2e7d32", dash: "dash" } }),
      line("permitted", s.position, s.permitted, { line: { color: "#f9a825" } }),
      line("intervention", s.position, s.intervention, { line: { color: "#c62828" } }),
    ], { xaxis: { title: { text: "position [m]" } }, yaxis: { title: { text: "km/h" }, rangemode: "tozero" } });
  }

  answer(action, answer, slot) {
    const node = $(slot);
    node.dataset.action = action;
    if (!answer.ok) {
      node.dataset.accepted = "false";
      node.textContent = `${action}: ${errorText(answer)}`;
      return;
    }
    const accepted = answer.data.accepted !== false;
    node.dataset.accepted = String(accepted);
    node.textContent = `${action}: ${accepted ? "accepted" : "refused"}${answer.data.reason ? ` (${answer.data.reason})` : ""}`;
  }

  pending(action, slot) {
    const node = $(slot);
    node.dataset.action = action;
    node.dataset.accepted = "";
    node.textContent = `${action}: sent…`;
  }

  /** Send a command; its answer shows in ``slot`` (the VC confirmations have their own). */
  async command(action, body, slot = "#command-answer", route = action) {
    this.pending(action, slot);
    this.answer(action, await api(this.path(route), { method: "POST", body }), slot);
  }

  /** Confirm the VC request of that kind and number; the answer is labelled with the kind. */
  async confirm(kind, number) {
    const confirmation = confirmRoutes[kind];
    await this.command(confirmation, { number }, "#request-answer", `confirmations/${confirmation}`);
  }

  async hold(action) {
    const answer = await api(this.path(action), { method: "POST" });
    const node = $("#driver-message");
    node.dataset.ok = String(answer.ok);
    node.textContent = answer.ok ? `${action}: ${answer.data.holder ? `held by ${answer.data.holder}` : "released"}` : `${action}: ${errorText(answer)}`;
    if (answer.ok) this.showHolder(answer.data.holder, answer.data.expires_at);
  }

  async sendJourney() {
    const journeyId = $("#journey-select").value;
    this.pending("journey-profile", "#journey-answer");
    const answer = await api(this.path("journey-profile"), { method: "POST", body: { journey_id: journeyId } });
    const node = $("#journey-answer");
    if (!answer.ok) {
      node.dataset.accepted = "false";
      node.textContent = `journey ${journeyId}: ${errorText(answer)}`;
      return;
    }
    node.dataset.accepted = String(answer.data.accepted);
    // The trackside's planner may have timed it later, to keep clear of the trains ahead.
    const delayed = answer.data.delay_s > 0 ? `, planned ${answer.data.delay_s} s later: ${answer.data.conflict}` : "";
    node.textContent = `journey ${answer.data.journey_id} v${answer.data.version}: ${answer.data.accepted ? "acknowledged" : "rejected"}${answer.data.reason ? ` (${answer.data.reason})` : ""}${delayed}`;
  }
}
