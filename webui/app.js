// Fleet page of the ATO-TS console: sign in, then show live vehicles pushed over WebSocket.
"use strict";

const tokenKey = "ato.token";
const $ = (selector) => document.querySelector(selector);

function showFleet(visible) {
  $("#login-panel").hidden = visible;
  $("#fleet-panel").hidden = !visible;
  $("#logout").hidden = !visible;
}

function setConnection(online) {
  const badge = $("#connection");
  badge.textContent = online ? "live" : "offline";
  badge.className = "badge " + (online ? "on" : "off");
}

function cell(text, numeric) {
  const td = document.createElement("td");
  td.textContent = text;
  if (numeric) td.className = "num";
  return td;
}

function renderFleet(vehicles) {
  const body = $("#fleet tbody");
  body.replaceChildren();
  $("#fleet-empty").hidden = vehicles.length > 0;
  for (const vehicle of vehicles) {
    const s = vehicle.status;
    const row = document.createElement("tr");
    row.dataset.vehicle = vehicle.id;
    row.className = vehicle.alive ? "alive" : "dead";
    row.append(
      cell(vehicle.id),
      cell(vehicle.alive ? "yes" : "no"),
      cell(s ? s.line_id : "–"),
      cell(s ? s.position_m.toFixed(1) : "–", true),
      cell(s ? (s.speed_mps * 3.6).toFixed(1) : "–", true),
      cell(s ? s.ato_state : "–"),
      cell(s ? s.etcs_mode : "–"),
      cell(s ? s.sc_state : "–"),
      cell(s ? s.sim_time_s.toFixed(1) : "–", true),
    );
    row.querySelector("td:nth-child(4)").dataset.field = "position";
    row.querySelector("td:nth-child(5)").dataset.field = "speed";
    body.append(row);
  }
}

let socket = null;
let retry = null;

function connect(token) {
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  socket = new WebSocket(`${scheme}://${location.host}/api/v1/ws/fleet?token=${encodeURIComponent(token)}`);
  socket.onopen = () => setConnection(true);
  socket.onmessage = (event) => {
    const frame = JSON.parse(event.data);
    if (frame.type === "fleet") renderFleet(frame.vehicles);
  };
  socket.onclose = (event) => {
    setConnection(false);
    if (event.code === 1008) { signOut(); return; }
    retry = setTimeout(() => connect(token), 1000);
  };
}

async function fetchFleet(token) {
  const response = await fetch("/api/v1/vehicles", { headers: { Authorization: `Bearer ${token}` } });
  if (response.status === 401) { signOut(); return; }
  if (response.ok) renderFleet(await response.json());
}

function start(token) {
  showFleet(true);
  fetchFleet(token);
  connect(token);
}

function signOut() {
  sessionStorage.removeItem(tokenKey);
  clearTimeout(retry);
  if (socket) { socket.onclose = null; socket.close(); socket = null; }
  setConnection(false);
  showFleet(false);
}

$("#login-form").addEventListener("submit", async (event) => {
  event.preventDefault();
  const body = new URLSearchParams(new FormData(event.target));
  const response = await fetch("/api/v1/auth/token", { method: "POST", body });
  if (!response.ok) {
    $("#login-error").textContent = response.status === 401 ? "Wrong user or password." : `Error ${response.status}`;
    return;
  }
  $("#login-error").textContent = "";
  const { access_token: token } = await response.json();
  sessionStorage.setItem(tokenKey, token);
  start(token);
});

$("#logout").addEventListener("click", signOut);

const saved = sessionStorage.getItem(tokenKey);
if (saved) start(saved);
