// The line map: the line's geodetic polyline drawn as SVG in a local projection (no map tiles:
// the console works without the internet), its stopping points, and a marker at a chainage.
// Projection: equirectangular about the polyline's mean latitude, metres east and north of its
// first point, scaled to fit with north up and one scale on both axes (true shape for lines of a
// few hundred kilometres).
const svgNs = "http://www.w3.org/2000/svg";
const width = 1000;
const height = 420;
const margin = 30;
const earthRadiusM = 6371000;

function svg(tag, attributes) {
  const node = document.createElementNS(svgNs, tag);
  for (const [name, value] of Object.entries(attributes)) node.setAttribute(name, value);
  return node;
}

/** The polyline point at a chainage [m], linearly between its two neighbours. */
export function pointAt(geodetic, chainageM) {
  if (chainageM <= geodetic[0].chainage_m) return geodetic[0];
  for (let i = 1; i < geodetic.length; i += 1) {
    const b = geodetic[i];
    if (chainageM <= b.chainage_m) {
      const a = geodetic[i - 1];
      const t = (chainageM - a.chainage_m) / Math.max(b.chainage_m - a.chainage_m, 1e-9);
      return {
        chainage_m: chainageM,
        latitude_deg: a.latitude_deg + t * (b.latitude_deg - a.latitude_deg),
        longitude_deg: a.longitude_deg + t * (b.longitude_deg - a.longitude_deg),
      };
    }
  }
  return geodetic[geodetic.length - 1];
}

export class LineMap {
  constructor(container) {
    this.container = container;
    this.line = null;
    this.start = null;
  }

  /** Draw ``line``; a line without a geodetic polyline says so instead. */
  setLine(line) {
    this.line = line;
    const points = line.geodetic || [];
    if (points.length < 2) {
      const note = document.createElement("p");
      note.className = "muted";
      note.dataset.map = "none";
      note.textContent = `${line.name}: no geodetic polyline, no map`;
      this.container.replaceChildren(note);
      this.start = null;
      return;
    }
    const project = projection(points);
    const root = svg("svg", { viewBox: `0 0 ${width} ${height}`, role: "img", "aria-label": `map of ${line.id}` });
    root.dataset.line = line.id;
    const track = svg("polyline", { class: "map-track", points: points.map((p) => project(p).join(",")).join(" ") });
    track.dataset.map = "track";
    track.dataset.points = String(points.length);
    root.append(track);
    const [x0, y0] = project(points[0]);
    const origin = svg("circle", { class: "map-origin", cx: x0, cy: y0, r: 4 });
    origin.append(svg("title", {}));
    origin.firstChild.textContent = "chainage 0 m";
    root.append(origin);
    for (const stop of line.stopping_points || []) {
      const [x, y] = project(pointAt(points, stop.position_m));
      const mark = svg("g", { class: "map-stop" });
      mark.dataset.mapStop = stop.id;
      mark.append(svg("circle", { cx: x, cy: y, r: 6 }));
      const label = svg("text", { x: x + 9, y: y - 7 });
      label.textContent = stop.name;
      mark.append(label);
      const title = svg("title", {});
      title.textContent = `${stop.name} (${stop.id}) at ${stop.position_m} m`;
      mark.append(title);
      root.append(mark);
    }
    this.start = svg("circle", { class: "map-start", r: 7, cx: -100, cy: -100 });
    this.start.dataset.map = "start";
    root.append(this.start);
    this.project = project;
    const scale = document.createElement("p");
    scale.className = "muted";
    scale.textContent = `${line.name}: ${(line.length_m / 1000).toFixed(2)} km, ${points.length} polyline points; north up`;
    this.container.replaceChildren(root, scale);
  }

  /** Mark the journey's start at ``chainageM`` [m]. */
  setStart(chainageM) {
    if (!this.start || !this.line || !Number.isFinite(chainageM)) return;
    const length = this.line.length_m;
    const wrapped = this.line.ring ? ((chainageM % length) + length) % length : Math.min(Math.max(chainageM, 0), length);
    const [x, y] = this.project(pointAt(this.line.geodetic, wrapped));
    this.start.setAttribute("cx", x);
    this.start.setAttribute("cy", y);
    this.start.dataset.chainageM = wrapped.toFixed(1);
  }
}

/** A function from a geodetic point to SVG (x, y): local metres, fitted into the view. */
function projection(points) {
  const meanLat = points.reduce((sum, p) => sum + p.latitude_deg, 0) / points.length;
  const cosLat = Math.cos((meanLat * Math.PI) / 180);
  const first = points[0];
  const local = (p) => [
    ((p.longitude_deg - first.longitude_deg) * Math.PI / 180) * earthRadiusM * cosLat,
    ((p.latitude_deg - first.latitude_deg) * Math.PI / 180) * earthRadiusM,
  ];
  // A loop, not Math.min(...): a long line's polyline has more points than a call has arguments.
  let [minE, maxE, minN, maxN] = [Infinity, -Infinity, Infinity, -Infinity];
  for (const point of points) {
    const [e, n] = local(point);
    [minE, maxE, minN, maxN] = [Math.min(minE, e), Math.max(maxE, e), Math.min(minN, n), Math.max(maxN, n)];
  }
  const scale = Math.min((width - 2 * margin) / Math.max(maxE - minE, 1), (height - 2 * margin) / Math.max(maxN - minN, 1));
  const offsetX = (width - scale * (maxE - minE)) / 2;
  const offsetY = (height - scale * (maxN - minN)) / 2;
  return (p) => {
    const [e, n] = local(p);
    return [+(offsetX + scale * (e - minE)).toFixed(1), +(height - offsetY - scale * (n - minN)).toFixed(1)];
  };
}
