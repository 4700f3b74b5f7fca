"""Figures of the ADF, written as PNG files by ``ato bench adf --plots DIR``.

The RD → AD → RD sequence (seed 000 §5: the supervisory controller's bumpless hand-over): the
applied force with the SC state shaded, and the speed.
"""

from __future__ import annotations

from pathlib import Path

from deploy.bench.adf_closed_loop import HandoverRecord
from deploy.bench.plant_plots import _figure
from protocol.units import MPS_PER_KMH

__all__ = ["HANDOVER_PLOT", "write_handover_plot"]

HANDOVER_PLOT = "adf_rd_ad_rd_handover.png"
STATE_COLOURS = {"RD": "tab:blue", "HRD2AD": "tab:purple", "AD": "tab:green", "HAD2RD": "tab:olive"}


def write_handover_plot(record: HandoverRecord, directory: Path) -> Path:
    """Draw the sequence; returns the file written."""
    directory.mkdir(parents=True, exist_ok=True)
    figure, (force_ax, speed_ax) = _figure(2, "RD → AD → RD hand-over (bologna-ring)")
    times = record.times_s
    start = 0
    for index in range(1, len(record.states) + 1):
        if index == len(record.states) or record.states[index] != record.states[start]:
            state = record.states[start]
            end = times[index] if index < len(times) else times[-1]
            for ax in (force_ax, speed_ax):
                ax.axvspan(times[start], end, color=STATE_COLOURS.get(state, "white"), alpha=0.12)
            force_ax.text(times[start], 0.0, state, fontsize=8, va="bottom")
            start = index
    force_ax.plot(times, record.forces_n / 1000.0, color="black", linewidth=1.0)
    force_ax.set_ylabel("applied force u [kN]")
    speed_ax.plot(times, record.speeds_mps / MPS_PER_KMH, color="tab:red", linewidth=1.0)
    speed_ax.set_ylabel("speed [km/h]")
    path = directory / HANDOVER_PLOT
    figure.savefig(path, dpi=110)
    return path
