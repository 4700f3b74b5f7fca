"""The run report: one self-contained HTML file (plots inlined as PNG) beside ``kpis.json``.

The plots are those of seed 000's field test (figs. 9–10: speed and its reference, the speed
error, the traction effort) and the run's own: the localisation error, the battery's state of
charge and the traction energy, a timeline of the ETCS mode, the ATO-OB state and the
supervisory controller's state, and each leg's driven speed per distance beside the offline
optimum's, with the energy certificate's numbers (``deploy.scenario.energy_certificate``).
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

from deploy.scenario.energy_certificate import OptimumProfile
from deploy.scenario.kpi_model import EnergyCertificate, FleetKpis, Kpis
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


def _optimum_figure(
    c: Mapping[str, np.ndarray], certificate: EnergyCertificate, profiles: Sequence[OptimumProfile]
) -> Figure:
    """Each leg's driven speed (truth) per distance from its departure, beside its optimum."""
    legs = certificate.legs
    figure, axes = plt.subplots(len(legs), 1, figsize=(10, 2.6 * len(legs)), squeeze=False)
    optima = {profile.name: profile for profile in profiles}
    for row, leg in zip(axes[:, 0], legs, strict=True):
        inside = (c["time_s"] >= leg.departure_s) & (c["time_s"] <= leg.arrival_s)
        start_m = float(np.interp(leg.departure_s, c["time_s"], c["position_m"]))
        row.plot(
            c["position_m"][inside] - start_m, c["speed_mps"][inside] / MPS_PER_KMH, label="driven"
        )
        optimum = optima.get(leg.stop)
        if optimum is not None:
            row.plot(
                optimum.distances_m, optimum.speeds_mps / MPS_PER_KMH, "--", label="optimum (truth)"
            )
        row.set_ylabel("km/h")
        row.legend(loc="upper right", fontsize=8)
        row.set_title(f"Leg to {leg.stop}: {_leg_energy_text(leg.driven_kwh, leg.optimum_kwh)}")
    axes[-1, 0].set_xlabel("distance from the departure [m]")
    return figure


def _leg_energy_text(driven_kwh: float, optimum_kwh: float | None) -> str:
    if optimum_kwh is None:
        return f"driven {driven_kwh:.3f} kWh, no optimum"
    return (
        f"driven {driven_kwh:.3f} kWh, optimum {optimum_kwh:.3f} kWh "
        f"({(driven_kwh / optimum_kwh - 1.0) * 100.0:+.1f} %)"
    )


def _energy_section(certificate: EnergyCertificate | None, fallbacks: int | None) -> str:
    if certificate is None:
        return "<p>No journey driven: no energy certificate.</p>"

    def kwh(value: float | None) -> str:
        return "–" if value is None else f"{value:.4f}"

    def ratio(value: float | None) -> str:
        return "–" if value is None else f"{value:.3f}"

    rows = "".join(
        f"<tr><td>{html.escape(leg.stop)}</td><td>{leg.departure_s:.1f}</td>"
        f"<td>{leg.arrival_s:.1f}</td><td>{leg.distance_m:.1f}</td><td>{kwh(leg.driven_kwh)}</td>"
        f"<td>{kwh(leg.plan_kwh)}</td><td>{kwh(leg.optimum_kwh)}</td>"
        f"<td>{ratio(leg.driven_vs_optimum)}</td></tr>"
        for leg in certificate.legs
    )
    c = certificate
    total = (
        f"<tr><th>journey</th><td></td><td></td><td></td><th>{kwh(c.driven_kwh)}</th>"
        f"<th>{kwh(c.plan_kwh)}</th><th>{kwh(c.optimum_kwh)}</th>"
        f"<th>{ratio(c.driven_vs_optimum)}</th></tr>"
    )
    return (
        "<table><tr><th>leg to</th><th>departure [s]</th><th>arrival [s]</th>"
        "<th>distance [m]</th><th>driven [kWh]</th><th>plan [kWh]</th><th>optimum [kWh]</th>"
        f"<th>driven / optimum</th></tr>{rows}{total}</table>"
        f"<p>Plan / optimum {ratio(c.plan_vs_optimum)}; regenerated {kwh(c.regenerated_kwh)} "
        f"kWh; legs planned without the energy optimiser: {fallbacks}.</p>"
    )


def _table(rows: Sequence[tuple[str, str]]) -> str:
    body = "".join(f"<tr><th>{html.escape(k)}</th><td>{html.escape(v)}</td></tr>" for k, v in rows)
    return f"<table>{body}</table>"


def _figures(
    kpis: Kpis, columns: Mapping[str, np.ndarray], optima: Sequence[OptimumProfile]
) -> tuple[list[str], str]:
    """The plots as PNG (base64), and the energy plot's image element ("" without legs)."""
    if not columns["time_s"].size:
        return [], ""
    figures = [
        _png(_speed_figure(columns)),
        _png(_position_figure(columns)),
        _png(_odometry_figure(columns)),
        _png(_timeline_figure(columns)),
    ]
    if kpis.energy is None or not kpis.energy.legs:
        return figures, ""
    png = _png(_optimum_figure(columns, kpis.energy, optima))
    return figures, f'<img alt="driven and optimal speed" src="data:image/png;base64,{png}">'


def _fleet_section(fleet: FleetKpis | None) -> str:
    """A multi-train run's trains, their least distance and headways ("" for one train)."""
    if fleet is None:
        return ""

    def number(value: float | None, form: str) -> str:
        return "–" if value is None else format(value, form)

    trains = "".join(
        f'<tr class="{"ok" if t.passed else "fail"}"><td>{html.escape(t.vehicle_id)}</td>'
        f"<td>{'passed' if t.passed else 'FAILED'}</td><td>{t.stops}</td>"
        f"<td>{number(t.max_arrival_delay_s, '+.1f')}</td><td>{t.held_s:.1f}</td>"
        f"<td>{t.eoa_stops}</td><td>{number(t.max_stop_error_m, '.3f')}</td>"
        f"<td>{t.etcs_sb_count}/{t.etcs_eb_count}/{t.vc_eb_count}</td></tr>"
        for t in fleet.trains
    )
    headways = "".join(
        f"<tr><td>{html.escape(h.stop)}</td><td>{html.escape(h.ahead)}</td>"
        f"<td>{html.escape(h.behind)}</td><td>{h.headway_s:.1f}</td></tr>"
        for h in fleet.headways
    )
    between = " behind ".join(fleet.min_distance_between) or "no train ahead"
    return f"""<h2>Trains</h2><table><tr><th>vehicle</th><th>verdict</th><th>stops</th>
<th>latest arrival [s]</th><th>held by its MA [s]</th><th>EoA stops</th>
<th>|stop error| max [m]</th><th>ETCS SB/EB, VC EB</th></tr>{trains}</table>
<p>Least distance from a train's front end to the rear end of the train ahead (truth):
{number(fleet.min_distance_m, ".1f")} m at {number(fleet.min_distance_at_s, ".1f")} s
({html.escape(between)}).</p>
<table><tr><th>stop</th><th>ahead</th><th>behind</th><th>headway [s]</th></tr>{headways}</table>
"""


def render_report(
    kpis: Kpis, columns: Mapping[str, np.ndarray], optima: Sequence[OptimumProfile] = ()
) -> str:
    """The report's HTML; ``optima``: each leg's offline optimum, for the energy plot."""
    figures, energy_figure = _figures(kpis, columns, optima)
    energy = _energy_section(kpis.energy, kpis.energy_plan_fallbacks)
    trains = _fleet_section(kpis.fleet)
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
        if k not in ("stops", "expectations", "vc_interventions", "energy", "fleet")
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
{trains}<h2>Stops</h2><table><tr><th>stop</th><th>planned arrival [s]</th><th>arrival error [s]</th>
<th>stop error [m]</th><th>ETCS interval [m]</th></tr>{stops}</table>
<h2>Energy: driven, plan and the offline optimum</h2>{energy}{energy_figure}
<h2>Plots</h2>{images}
<h2>KPIs</h2>{_table(scalars)}
<h2>Vital Control interventions</h2><pre>{interventions}</pre>
</body></html>
"""
