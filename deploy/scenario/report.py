"""The run report: one self-contained HTML file (plots inlined as PNG) beside ``kpis.json``.

The plots are those of seed 000's field test (figs. 9–10: speed and its reference, the speed
error, the traction effort) and the run's own: the localisation error, the battery's state of
charge and the traction energy, and a timeline of the ETCS mode, the ATO-OB state and the
supervisory controller's state.
"""

from __future__ import annotations

import base64
import html
import io
import json
from collections.abc import Mapping, Sequence

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from deploy.scenario.kpi_model import Kpis
from protocol.units import J_PER_KWH, MPS_PER_KMH

__all__ = ["render_report"]


def _png(figure: Figure) -> str:
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=90, bbox_inches="tight")
    plt.close(figure)
    return base64.b64encode(buffer.getvalue()).decode("ascii")


def _speed_figure(c: Mapping[str, np.ndarray]) -> Figure:
    figure, (speed, error, force) = plt.subplots(3, 1, figsize=(10, 8), sharex=True)
    t = c["time_s"]
    speed.plot(t, c["speed_mps"] / MPS_PER_KMH, label="speed (truth)")
    speed.plot(t, c["reference_speed_mps"] / MPS_PER_KMH, "--", label="reference (ADF)")
    speed.plot(t, c["mrsp_mps"] / MPS_PER_KMH, ":", label="MRSP")
    speed.plot(
        t, c["permitted_speed_mps"] / MPS_PER_KMH, "-.", linewidth=0.8, label="ETCS permitted"
    )
    speed.set_ylabel("km/h")
    speed.legend(loc="upper right", fontsize=8)
    speed.set_title("Speed and reference (seed 000 fig. 9)")
    error.plot(t, (c["speed_mps"] - c["reference_speed_mps"]) / MPS_PER_KMH)
    error.set_ylabel("v − v_ref [km/h]")
    error.set_title("Speed error (seed 000 fig. 10)")
    force.plot(t, c["force_n"] / 1000.0, label="applied")
    force.plot(t, c["force_demand_n"] / 1000.0, linewidth=0.8, label="demand")
    force.set_ylabel("kN")
    force.set_xlabel("simulated time [s]")
    force.legend(loc="upper right", fontsize=8)
    force.set_title("Traction effort")
    return figure


def _position_figure(c: Mapping[str, np.ndarray]) -> Figure:
    figure, (position, energy) = plt.subplots(2, 1, figsize=(10, 5.5), sharex=True)
    t = c["time_s"]
    position.plot(t, c["position_m"] / 1000.0)
    position.set_ylabel("km")
    position.set_title("Position")
    energy.plot(t, c["traction_energy_j"] / J_PER_KWH, label="traction energy [kWh]")
    if np.isfinite(c["soc"]).any():
        soc = energy.twinx()
        soc.plot(t, c["soc"] * 100.0, color="tab:green", label="SOC [%]")
        soc.set_ylabel("SOC [%]")
    energy.set_ylabel("kWh")
    energy.set_xlabel("simulated time [s]")
    energy.set_title("Energy and state of charge")
    return figure


def _odometry_figure(c: Mapping[str, np.ndarray]) -> Figure:
    """ETCS's confidence interval around its estimate, and both estimates' errors (truth)."""
    figure, axes = plt.subplots(1, 1, figsize=(10, 3.2))
    t, truth = c["time_s"], c["position_m"]
    interval = c["odometry_interval_m"]
    axes.fill_between(
        t, -interval, interval, color="tab:blue", alpha=0.15, label="ETCS confidence interval [m]"
    )
    axes.plot(
        t, c["etcs_position_m"] - truth, color="tab:blue", lw=1, label="ETCS estimate − truth [m]"
    )
    axes.plot(
        t,
        c["estimated_position_m"] - truth,
        color="tab:orange",
        lw=1,
        label="fused estimate − truth [m]",
    )
    axes.set_ylabel("m")
    axes.set_xlabel("simulated time [s]")
    axes.legend(loc="upper left", fontsize=8)
    axes.set_title("Odometry: ETCS's interval, and where the estimates were")
    return figure


def _timeline_figure(c: Mapping[str, np.ndarray]) -> Figure:
    figure, axes = plt.subplots(1, 1, figsize=(10, 2.6))
    t = c["time_s"]
    rows = (("ETCS", c["etcs_mode"]), ("ATO-OB", c["ato_state"]), ("SC", c["sc_state"]))
    colours = plt.get_cmap("tab20")
    names = sorted({str(v) for _, values in rows for v in values})
    for row, (_, values) in enumerate(rows):
        start = 0
        for k in range(1, len(values) + 1):
            if k == len(values) or values[k] != values[start]:
                end = t[k] if k < len(values) else t[-1]
                name = str(values[start])
                axes.broken_barh(
                    [(t[start], max(end - t[start], 1e-3))],
                    (row - 0.4, 0.8),
                    color=colours(names.index(name) % 20),
                )
                if end - t[start] > 0.04 * (t[-1] - t[0] + 1e-9):
                    axes.text((t[start] + end) / 2, row, name, ha="center", va="center", fontsize=7)
                start = k
    axes.set_yticks(range(len(rows)), [name for name, _ in rows])
    axes.set_xlabel("simulated time [s]")
    axes.set_title("Mode timeline")
    return figure


def _table(rows: Sequence[tuple[str, str]]) -> str:
    body = "".join(f"<tr><th>{html.escape(k)}</th><td>{html.escape(v)}</td></tr>" for k, v in rows)
    return f"<table>{body}</table>"


def render_report(kpis: Kpis, columns: Mapping[str, np.ndarray]) -> str:
    """The report's HTML."""
    figures: list[str] = []
    if columns["time_s"].size:
        figures = [
            _png(_speed_figure(columns)),
            _png(_position_figure(columns)),
            _png(_odometry_figure(columns)),
            _png(_timeline_figure(columns)),
        ]
    expectations = "".join(
        f'<tr class="{"ok" if e.ok else "fail"}"><td>{"✔" if e.ok else "✘"}</td>'
        f"<td>{html.escape(e.name)}</td><td>{html.escape(e.detail)}</td></tr>"
        for e in kpis.expectations
    )
    stops = "".join(
        f"<tr><td>{html.escape(s.name)}</td><td>{s.planned_arrival_s:.1f}</td>"
        f"<td>{s.arrival_error_s:+.2f}</td><td>{s.stop_error_m:+.3f}</td>"
        f"<td>{s.odometry_interval_m:.1f}</td></tr>"
        for s in kpis.stops
    )
    written = kpis.model_dump(mode="json")
    scalars = [
        (k, json.dumps(v))
        for k, v in written.items()
        if k not in ("stops", "expectations", "vc_interventions")
    ]
    verdict = "passed" if kpis.passed else "FAILED"
    interventions = html.escape(json.dumps(written["vc_interventions"], indent=1))
    images = "".join(f'<img alt="plot" src="data:image/png;base64,{p}">' for p in figures)
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8">
<title>ato run {html.escape(kpis.scenario)}</title>
<style>
body {{ font-family: sans-serif; margin: 2em; max-width: 1000px; }}
table {{ border-collapse: collapse; margin: 1em 0; }}
td, th {{ border: 1px solid #ccc; padding: 0.2em 0.6em; text-align: left; font-size: 0.9em; }}
tr.ok td:first-child {{ color: green; }} tr.fail td {{ color: #b00; }}
img {{ max-width: 100%; margin: 1em 0; }}
</style></head><body>
<h1>Scenario {html.escape(kpis.scenario)}: {verdict}</h1>
<p>Seed {kpis.seed}, {kpis.sim_time_s:.1f} s simulated in
{kpis.wall_time_s:.1f} s ({kpis.real_time_factor:.1f}× real time).</p>
<h2>Expectations</h2><table>{expectations}</table>
<h2>Stops</h2><table><tr><th>stop</th><th>planned arrival [s]</th><th>arrival error [s]</th>
<th>stop error [m]</th><th>ETCS interval [m]</th></tr>{stops}</table>
<h2>Plots</h2>{images}
<h2>KPIs</h2>{_table(scalars)}
<h2>Vital Control interventions</h2><pre>{interventions}</pre>
</body></html>
"""
