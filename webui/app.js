// Entry point of the ATO-TS console: sign-in, and the views by URL hash
// (#/fleet, #/vehicle/ID, #/planner, #/report/ID). Plain ES modules, no build step.
import { leaseEnd, openSocket, setUnauthorisedHandler, token } from "./api.js";
import { DriverView } from "./driver.js";
import { FleetView } from "./fleet.js";
import { PlannerView } from "./planner.js";
import { ReportView } from "./report.js";

const $ = (selector) => document.querySelector(selector);

function setConnection(online) {
  const badge = $("#connection");
  badge.textContent = online ? "live" : "offline";
  badge.className = "badge " + (online ? "on" : "off");
}

/** The console's session socket, open whatever the view: while it is, the trackside renews this
 * user's vehicle holds (a closed or crashed console loses them when their lease ends). */
class Presence {
  constructor() { this.socket = null; this.retry = null; }

  open() {
    this.socket = openSocket("/ws/session");
    this.socket.onmessage = (event) => {
      const frame = JSON.parse(event.data);
      if (frame.type === "holds") showHolds(frame.holds);
    };
    this.socket.onclose = (event) => {
      this.socket = null;
      if (event.code === 1008) { if (token.get()) signOut(); return; }
      this.retry = setTimeout(() => this.open(), 1000);
    };
  }

  close() {
    clearTimeout(this.retry);
    if (this.socket) { this.socket.onclose = null; this.socket.close(); this.socket = null; }
    showHolds({});
  }
}

function showHolds(holds) {
  const held = Object.entries(holds).map(([vehicle, until]) => `${vehicle} (lease to ${leaseEnd(until)})`);
  $("#holding").textContent = held.length ? `holding ${held.join(", ")}` : "";
}

const presence = new Presence();
const views = {
  fleet: new FleetView(setConnection),
  driver: new DriverView(setConnection),
  planner: new PlannerView(),
  report: new ReportView(),
};
let current = null;

function route() {
  const parts = location.hash.replace(/^#\/?/, "").split("/").map(decodeURIComponent);
  const name = { vehicle: "driver", planner: "planner", report: "report" }[parts[0]] || "fleet";
  if (current) current.hide();
  for (const panel of document.querySelectorAll("[data-view]")) panel.hidden = panel.dataset.view !== name;
  current = views[name];
  current.show(parts[1]);
}

function signedIn(visible) {
  $("#login-panel").hidden = visible;
  $("#logout").hidden = !visible;
  $("#nav").hidden = !visible;
  if (!visible) for (const panel of document.querySelectorAll("[data-view]")) panel.hidden = true;
}

function start() {
  signedIn(true);
  presence.open();
  route();
}

function signOut() {
  const saved = token.get();
  token.clear();
  if (current) current.hide();
  current = null;
  presence.close();
  setConnection(false);
  signedIn(false);
  if (saved) fetch("/api/v1/auth/logout", { method: "POST", headers: { Authorization: `Bearer ${saved}` } });
}

setUnauthorisedHandler(() => { if (token.get()) signOut(); });

$("#login-form").addEventListener("submit", async (event) => {
  event.preventDefault();
  const body = new URLSearchParams(new FormData(event.target));
  const response = await fetch("/api/v1/auth/token", { method: "POST", body });
  if (!response.ok) {
    $("#login-error").textContent = response.status === 401 ? "Wrong user or password." : `Error ${response.status}`;
    return;
  }
  $("#login-error").textContent = "";
  const { access_token: accessToken } = await response.json();
  token.set(accessToken);
  $("#whoami").textContent = new FormData(event.target).get("username");
  start();
});

$("#logout").addEventListener("click", signOut);
window.addEventListener("hashchange", () => { if (token.get()) route(); });

if (token.get()) start();
