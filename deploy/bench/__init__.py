"""Benches and per-part harnesses: everything that drives or scores a part from outside.

``onboard/`` holds only what runs in the onboard process (ARCHITECTURE.md, "The truth
boundary"); what drives a part in closed loop for tests and benches, scores it against the
truth, or times it lives here. A module is named after the part it exercises.

Benches, one per ``ato bench`` subcommand, and their figures:

- :mod:`~deploy.bench.zenoh_bench` (``zenoh``), :mod:`~deploy.bench.trackdb_bench`
  (``trackdb``), :mod:`~deploy.bench.plant_bench` (``plant``), :mod:`~deploy.bench.adf_bench`
  (``adf``), :mod:`~deploy.bench.vc_bench` (``vc``), :mod:`~deploy.bench.sfa_bench` (``sfa``),
  :mod:`~deploy.bench.run_bench` (``run``), :mod:`~deploy.bench.trackside_bench`
  (``trackside``);
- :mod:`~deploy.bench.plant_plots`, :mod:`~deploy.bench.adf_plots`: their PNG figures.

Harnesses of one part:

- ADF: :mod:`~deploy.bench.adf_closed_loop`, AD and the RD → AD → RD hand-over on the point
  mass;
- VC: :mod:`~deploy.bench.vc_responder` (a test double of the ATO-OB and its operator),
  :mod:`~deploy.bench.vc_scenarios` and :mod:`~deploy.bench.vc_catalogue` (the seeds' 36
  scenarios), :mod:`~deploy.bench.vc_runner` (one scenario in lockstep, measured, behind
  ``ato run vc-*``), :mod:`~deploy.bench.vc_fused_speed` (what supervising the fused speed
  gains);
- sensor fusion: :mod:`~deploy.bench.sfa_drive` (an emulated drive),
  :mod:`~deploy.bench.sfa_emulator` (the emulator on a socket, ``ato sfa emulate``),
  :mod:`~deploy.bench.sfa_lockstep` (the chain in lockstep against the truth,
  ``ato sfa record``), :mod:`~deploy.bench.sfa_recording` (recordings and their replay,
  ``ato sfa replay``);
- VCU: :mod:`~deploy.bench.vcu_mission` (seed 003 §7.1–7.2 on the point mass),
  :mod:`~deploy.bench.vcu_manoeuvres` (§7.3–7.4 on the bogie model).

Nothing is imported here: each module loads what it needs when it is used.
"""

__all__ = []
