// The track strip: the line drawn straight, its stopping points, balise groups and the train.
import { element } from "./api.js";

const svgNs = "http://www.w3.org/2000/svg";
const width = 1000;
const height = 70;

function svg(tag, attributes) {
  const node = document.createElementNS(svgNs, tag);
  for (const [name, value] of Object.entries(attributes)) node.setAttribute(name, value);
  return node;
}

export class TrackStrip {
  constructor(container) {
    this.container = container;
    this.line = null;
    this.train = null;
  }

  x(chainageM) {
    return 10 + ((width - 20) * chainageM) / this.line.length_m;
  }

  setLine(line) {
    this.line = line;
    const root = svg("svg", { viewBox: `0 0 ${width} ${height}`, role: "img", "aria-label": `track ${line.id}` });
    root.append(svg("line", { x1: 10, x2: width - 10, y1: 35, y2: 35, class: "rail" }));
    for (const group of line.balise_groups || []) {
      const mark = svg("rect", { x: this.x(group.position_m) - 3, y: 38, width: 6, height: 6, class: "balise" });
      mark.dataset.balise = String(group.id);
      mark.append(svg("title", {}));
      mark.firstChild.textContent = `balise group ${group.id} at ${group.position_m} m`;
      root.append(mark);
    }
    for (const stop of line.stopping_points || []) {
      const x = this.x(stop.position_m);
      const mark = svg("g", { class: "station" });
      mark.dataset.station = stop.id;
      mark.append(svg("line", { x1: x, x2: x, y1: 18, y2: 35 }));
      const label = svg("text", { x, y: 14, "text-anchor": "middle" });
      label.textContent = stop.name;
      mark.append(label);
      root.append(mark);
    }
    this.train = svg("polygon", { class: "train", points: "" });
    this.train.dataset.train = "";
    root.append(this.train);
    this.container.replaceChildren(root, element("p", { class: "muted", text: `${line.name}: ${(line.length_m / 1000).toFixed(2)} km${line.ring ? ", ring" : ""}` }));
  }

  setTrain(positionM) {
    if (!this.line || positionM === null || positionM === undefined) return;
    const wrapped = this.line.ring ? ((positionM % this.line.length_m) + this.line.length_m) % this.line.length_m : positionM;
    const x = this.x(Math.min(Math.max(wrapped, 0), this.line.length_m));
    this.train.setAttribute("points", `${x - 8},26 ${x + 8},31 ${x - 8},36`);
    this.train.dataset.positionM = wrapped.toFixed(1);
  }
}
