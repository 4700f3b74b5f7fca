// REST and WebSocket access for the console: the bearer token, JSON calls, unit helpers.
const tokenKey = "ato.token";

export const token = {
  get: () => sessionStorage.getItem(tokenKey),
  set: (value) => sessionStorage.setItem(tokenKey, value),
  clear: () => sessionStorage.removeItem(tokenKey),
};

let onUnauthorised = () => {};
export function setUnauthorisedHandler(handler) { onUnauthorised = handler; }

/** Call the API; answers {status, ok, data} and never throws on an HTTP error. */
export async function api(path, { method = "GET", body } = {}) {
  const headers = { Authorization: `Bearer ${token.get()}` };
  const init = { method, headers };
  if (body !== undefined) {
    headers["Content-Type"] = "application/json";
    init.body = JSON.stringify(body);
  }
  let response;
  try {
    response = await fetch(`/api/v1${path}`, init);
  } catch (error) {
    return { status: 0, ok: false, data: { detail: String(error) } };
  }
  if (response.status === 401) onUnauthorised();
  const text = await response.text();
  let data = null;
  try { data = text ? JSON.parse(text) : null; } catch { data = { detail: text }; }
  return { status: response.status, ok: response.ok, data };
}

/** The human text of an error answer (FastAPI's detail may be a string, a list or an object). */
export function errorText(answer) {
  const detail = answer.data && answer.data.detail;
  if (typeof detail === "string") return `${answer.status}: ${detail}`;
  if (Array.isArray(detail)) return `${answer.status}: ${detail.map((d) => d.msg || JSON.stringify(d)).join("; ")}`;
  if (detail && detail.message) return `${answer.status}: ${detail.message}`;
  return `HTTP ${answer.status}`;
}

/** A WebSocket to the API. The bearer token goes in the first message, never in the URL (URLs
 * end up in logs); the trackside closes the socket with 1008 when it is missing or invalid. */
export function openSocket(path) {
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  const socket = new WebSocket(`${scheme}://${location.host}/api/v1${path}`);
  socket.addEventListener("open", () => socket.send(JSON.stringify({ type: "auth", token: token.get() })));
  return socket;
}

/** A lease's end as local wall-clock time (HH:MM:SS), or "" for none. */
export function leaseEnd(isoTime) {
  if (!isoTime) return "";
  return new Date(isoTime).toLocaleTimeString([], { hour: "2-digit", minute: "2-digit", second: "2-digit", hour12: false });
}

export const kmh = (mps) => (mps === null || mps === undefined ? null : mps * 3.6);
export const fixed = (value, digits = 1) =>
  value === null || value === undefined || Number.isNaN(value) ? "–" : Number(value).toFixed(digits);

export function element(tag, attributes = {}, ...children) {
  const node = document.createElement(tag);
  for (const [name, value] of Object.entries(attributes)) {
    if (name === "dataset") Object.assign(node.dataset, value);
    else if (name === "text") node.textContent = value;
    else if (name.startsWith("on")) node.addEventListener(name.slice(2), value);
    else node.setAttribute(name, value);
  }
  node.append(...children);
  return node;
}

// The Energy Manager's figures (StatusReport.energy, SI) in the console's units.
export const J_PER_KWH = 3.6e6;
export function socText(energy) {
  return energy && energy.soc !== null && energy.soc !== undefined ? (100 * energy.soc).toFixed(1) : "–";
}
export function kwhText(joules) {
  return joules === null || joules === undefined ? "–" : (joules / J_PER_KWH).toFixed(2);
}
