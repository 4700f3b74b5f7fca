// Fleet overview: every vehicle seen, pushed over WS /api/v1/ws/fleet.
import { api, element, fixed, kmh, kwhText, leaseEnd, openSocket, socText } from "./api.js";

function cell(text, numeric, field) {
  const td = element("td", { text: text });
  if (numeric) td.className = "num";
  if (field) td.dataset.field = field;
  return td;
}

function operatorCell(simulated) {
  const td = element("td", { dataset: { field: "operator" } });
  if (simulated === true) td.append(element("span", { class: "badge warn", text: "simulated" }));
  else td.textContent = simulated === false ? "person" : "–";
  return td;
}

function marginCell(energy) {
  const td = cell(kwhText(energy ? energy.margin_j : null), true, "energy-margin");
  if (energy && energy.short) td.classList.add("alarm");
  return td;
}

export function renderFleet(vehicles) {
  const body = document.querySelector("#fleet tbody");
  body.replaceChildren();
  document.querySelector("#fleet-empty").hidden = vehicles.length > 0;
  for (const vehicle of vehicles) {
    const s = vehicle.status;
    const row = element("tr", { dataset: { vehicle: vehicle.id }, class: vehicle.alive ? "alive" : "dead" });
    row.append(
      cell(vehicle.id),
      cell(vehicle.alive ? "yes" : "no"),
      cell(s ? s.line_id : "–"),
      cell(s ? fixed(s.position_m) : "–", true, "position"),
      cell(s ? fixed(kmh(s.speed_mps)) : "–", true, "speed"),
      cell(s ? s.ato_state : "–"),
      cell(s ? s.etcs_mode : "–"),
      cell(s ? s.sc_state : "–"),
      cell(socText(s && s.energy), true, "soc"),
      cell(kwhText(s && s.energy ? s.energy.energy_to_go_j : null), true, "energy-to-go"),
      marginCell(s && s.energy),
      cell(s ? fixed(s.sim_time_s) : "–", true),
      cell(vehicle.holder || "–", false, "holder"),
      cell(vehicle.holder ? leaseEnd(vehicle.hold_expires_at) : "–", false, "lease"),
      operatorCell(vehicle.simulated_operator),
      element("td", {}, element("a", { href: `#/vehicle/${encodeURIComponent(vehicle.id)}`, dataset: { open: vehicle.id }, text: "Drive" })),
    );
    body.append(row);
  }
}

export class FleetView {
  constructor(setConnection) {
    this.setConnection = setConnection;
    this.socket = null;
    this.retry = null;
  }

  async show() {
    const answer = await api("/vehicles");
    if (answer.ok) renderFleet(answer.data);
    this.connect();
  }

  connect() {
    this.socket = openSocket("/ws/fleet");
    this.socket.onopen = () => this.setConnection(true);
    this.socket.onmessage = (event) => {
      const frame = JSON.parse(event.data);
      if (frame.type === "fleet") renderFleet(frame.vehicles);
    };
    this.socket.onclose = (event) => {
      this.setConnection(false);
      if (event.code !== 1008) this.retry = setTimeout(() => this.connect(), 1000);
    };
  }

  hide() {
    clearTimeout(this.retry);
    if (this.socket) { this.socket.onclose = null; this.socket.close(); this.socket = null; }
  }
}
