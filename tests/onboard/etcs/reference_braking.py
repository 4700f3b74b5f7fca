"""Reference numbers for the ETCS braking curves, computed without ``onboard.etcs``.

Written from DOMAIN.md §1.1–1.5 and §6 alone, with the URV's default train data restated by
hand, for a uniform deceleration (level track, or one constant gradient under the whole braking
distance) where every curve has a closed form: d = V²/(2A). The tests compare the library with
these functions; run the module to print the documented cases::

    .venv/bin/python -m tests.onboard.etcs.reference_braking
"""

from __future__ import annotations

import sys

G = 9.81

# The URV (onboard/etcs/values.py), by hand: 15 kN on 15 t with 8 % rotating mass; gamma train.
A_BRAKE_EMERGENCY = 15_000.0 / (15_000.0 * 1.08)
A_BRAKE_SERVICE = 0.7
K_DRY, K_WET = 0.9, 0.9
T_BRAKE_EMERGENCY, T_BRAKE_SERVICE, T_TRACTION_CUT_OFF = 1.0, 1.5, 0.5

# A.3.1 fixed values and A.3.2 national defaults that the curves use.
T_WARNING, T_DRIVER = 2.0, 4.0
M_ROTATING_MIN, M_ROTATING_MAX = 2.0, 15.0
M_NVAVADH = 0.0
A_EST2_MAX = 0.4


def from_kmh(speed_kmh: float) -> float:
    return speed_kmh / 3.6


def margin_kmh(v_kmh: float, dv_min: float, dv_max: float, v_min: float, v_max: float) -> float:
    """A ceiling-speed margin in km/h, §1.1's law."""
    if v_kmh <= v_min:
        return dv_min
    return min(dv_min + (dv_max - dv_min) / (v_max - v_min) * (v_kmh - v_min), dv_max)


def dv_ebi_kmh(v_kmh: float) -> float:
    return margin_kmh(v_kmh, 7.5, 15.0, 110.0, 210.0)


def dv_sbi_kmh(v_kmh: float) -> float:
    return margin_kmh(v_kmh, 5.5, 10.0, 110.0, 210.0)


def dv_warning_kmh(v_kmh: float) -> float:
    return margin_kmh(v_kmh, 4.0, 5.0, 110.0, 140.0)


def v_ura_kmh(v_kmh: float) -> float:
    """SUBSET-041's speed accuracy: 2 km/h to 30 km/h, then linear to 12 km/h at 500 km/h."""
    if v_kmh <= 30.0:
        return 2.0
    return min(2.0 + (v_kmh - 30.0) * 10.0 / 470.0, 12.0)


def gradient_deceleration(gradient_permille: float) -> float:
    m_rotating = M_ROTATING_MAX if gradient_permille > 0 else M_ROTATING_MIN
    return G * gradient_permille / (1000.0 + 10.0 * m_rotating)


def stop_curves(
    v_kmh: float, gradient_permille: float = 0.0, a_est: float = 0.0
) -> dict[str, float]:
    """Distances [m] before a 0 km/h EoA, with the SvL at the EoA, at ``v_kmh``.

    Keys: ``ebd``, ``sbd`` (the curves at that speed), ``ebi``, ``sbi2``, ``w_svl``,
    ``p_svl``, ``i_svl`` (limits of the SvL) and ``sbi1``, ``w_eoa``, ``p_eoa``, ``i_eoa``
    (limits of the EoA).
    """
    v = from_kmh(v_kmh)
    a_safe = K_DRY * (K_WET + M_NVAVADH * (1 - K_WET)) * A_BRAKE_EMERGENCY
    a_safe += gradient_deceleration(gradient_permille)
    a_expected = A_BRAKE_SERVICE + gradient_deceleration(gradient_permille)
    t_bs1 = t_bs2 = T_BRAKE_SERVICE
    t_traction = max(T_TRACTION_CUT_OFF - (T_WARNING + t_bs2), 0.0)
    t_berem = max(T_BRAKE_EMERGENCY - t_traction, 0.0)
    t_indication = max(0.8 * T_BRAKE_SERVICE, 5.0) + T_DRIVER
    v_delta0 = from_kmh(v_ura_kmh(v_kmh))
    a_est1 = max(a_est, 0.0)
    v_delta1 = a_est1 * t_traction
    v_delta2 = min(a_est1, A_EST2_MAX) * t_berem
    v_bec = v + v_delta0 + v_delta1 + v_delta2
    d_bec = (v + v_delta0 + v_delta1 / 2) * t_traction + (
        v + v_delta0 + v_delta1 + v_delta2 / 2
    ) * t_berem
    ebi = v_bec**2 / (2 * a_safe) + d_bec
    sbi2 = ebi + v * t_bs2
    sbi1 = v**2 / (2 * a_expected) + v * t_bs1
    return {
        "ebd": v**2 / (2 * a_safe),
        "sbd": v**2 / (2 * a_expected),
        "ebi": ebi,
        "sbi2": sbi2,
        "w_svl": sbi2 + v * T_WARNING,
        "p_svl": sbi2 + v * T_DRIVER,
        "i_svl": sbi2 + v * T_DRIVER + v * t_indication,
        "sbi1": sbi1,
        "w_eoa": sbi1 + v * T_WARNING,
        "p_eoa": sbi1 + v * T_DRIVER,
        "i_eoa": sbi1 + v * T_DRIVER + v * t_indication,
    }


def main() -> None:
    out = sys.stdout
    for gradient in (0.0, -10.0):
        out.write(f"160 km/h to a 0 km/h EoA (= SvL), gradient {gradient} ‰, A_est 0\n")
        for name, value in stop_curves(160.0, gradient).items():
            out.write(f"  {name:6s} {value:10.3f} m\n")
    out.write("margins [km/h]      dV_ebi  dV_sbi  dV_warning\n")
    for speed in (100.0, 160.0, 210.0):
        ebi, sbi, warning = dv_ebi_kmh(speed), dv_sbi_kmh(speed), dv_warning_kmh(speed)
        out.write(f"  at {speed:5.0f} km/h   {ebi:6.2f}  {sbi:6.2f}  {warning:6.2f}\n")


if __name__ == "__main__":
    main()
