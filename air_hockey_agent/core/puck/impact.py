"""Puck-rim impact (Routh model), thesis eq. 3.2-3.4, in the impact frame of one rim.

Impact frame: ``b`` along the rim, ``n`` the inward normal (into the table), right-handed with z up
(``n = Rz(+90 deg) b``). A puck approaching the rim has ``vn < 0``. The puck is a uniform disc
(I = m r^2 / 2); its contact point slips along the rim with ``c = vb + r * omega``.

* Sticking (eq. 3.2), when ``(1 + beta) |c| <= 3 mu (1 + e) |vn|``: the tangential impulse stops the
  slip, ``P_b = -m c / 3``, when the tangential restitution ``beta`` is 0 (the thesis). With ``beta`` in
  [-1, 1] it leaves ``-beta c`` of it, ``P_b = -(1 + beta) m c / 3`` (Walton's three-parameter impact,
  e.g. Brach, "Mechanical Impact Dynamics", 1991): -1 is a rim without tangential impulse, 1 reverses the
  slip. Real rims push far less along themselves than Routh's impact does (issue #13: another engine's
  tangential impulse stays far below Coulomb's; no constant (e, mu_rim) fits), and a small mu_rim alone
  softens only the sliding impacts.
* Sliding (eq. 3.3) otherwise: ``P_b = mu s (1 + e) m vn`` with ``s = sign(c)``, opposing the slip.
* In both, ``P_n = -(1 + e) m vn`` and the post-impact velocities follow eq. 3.4:
  ``vb' = vb + P_b/m``, ``vn' = vn + P_n/m``, ``omega' = omega + 2 P_b / (m r)``.

The mass cancels. The two branches agree on the switching boundary (tested).

Real rims lose more at faster impacts (issue #13: another engine's restitution is about 0.96 below
0.5 m/s normal speed and 0.67 above 2 m/s). With ``slope`` > 0 the restitution is
``e(vn) = max(e0 - slope max(|vn| - knee, 0), e_min)``: constant ``e0`` up to the ``knee`` speed, then
falling linearly to the floor ``e_min`` where it levels off. The thesis's constant e is ``slope = 0``;
the Jacobians include how e changes with vn.
"""
from __future__ import annotations

from typing import NamedTuple


class ImpactResult(NamedTuple):
    vb: float
    vn: float
    omega: float
    sliding: bool
    jacobian: tuple  # 3x3 as row tuples: d(vb', vn', omega') / d(vb, vn, omega) (tuples: cheaper than an array
    #                  for the caller, which only reads the nine entries)


def is_sliding(vb: float, vn: float, omega: float, radius: float, restitution: float, friction: float,
               tangential: float = 0.0) -> bool:
    """Branch selection: True for the sliding impact (eq. 3.3), False for sticking (eq. 3.2); ``restitution``
    is the impact's (speed-dependent) e, ``tangential`` the tangential restitution beta."""
    slip = vb + radius * omega
    return (1.0 + tangential) * abs(slip) > 3.0 * friction * (1.0 + restitution) * abs(vn)


def speed_restitution(restitution: float, slope: float, vn: float, floor: float = 0.0,
                      knee: float = 0.0) -> tuple[float, float]:
    """Restitution of an impact at normal velocity ``vn`` [m/s] (< 0): ``restitution`` up to the normal
    speed ``knee`` [m/s], then falling by ``slope`` [s/m], never below ``floor`` (nor above
    ``restitution``: a floor above it makes e constant); and its derivative d e / d vn."""
    e = restitution - slope * (abs(vn) - knee)
    if slope == 0.0 or e >= restitution:
        return restitution, 0.0
    if e <= floor:
        return min(floor, restitution), 0.0
    return e, (slope if vn < 0.0 else -slope)


def rim_impact(vb: float, vn: float, omega: float, radius: float, restitution: float,
               friction: float, slope: float = 0.0, floor: float = 0.0, tangential: float = 0.0,
               knee: float = 0.0) -> ImpactResult:
    """Post-impact (vb, vn, omega) [m/s, m/s, rad/s] and the branch's Jacobian S_j (thesis sec. 4.2);
    ``restitution`` falls by ``slope`` [s/m] per m/s of normal speed beyond ``knee`` [m/s] down to
    ``floor``, ``tangential`` is the tangential restitution beta [-] of a sticking impact (module
    docstring)."""
    mu, r = friction, radius
    e, de = speed_restitution(restitution, slope, vn, floor, knee)
    dvn = -e - vn * de  # d vn' / d vn
    if is_sliding(vb, vn, omega, r, e, mu, tangential):
        s = 1.0 if vb + r * omega > 0.0 else -1.0
        k = mu * s * (1.0 + e)  # P_b / (m vn)
        dk = mu * s * de * vn   # vn * d k / d vn
        jac = ((1.0, k + dk, 0.0),
               (0.0, dvn, 0.0),
               (0.0, 2.0 * (k + dk) / r, 1.0))
        return ImpactResult(vb + k * vn, -e * vn, omega + 2.0 * k * vn / r, True, jac)
    q = (1.0 + tangential) / 3.0  # -P_b / (m c): a third of the slip for Routh's full stick (beta = 0)
    slip = vb + r * omega
    jac = ((1.0 - q, 0.0, -q * r),
           (0.0, dvn, 0.0),
           (-2.0 * q / r, 0.0, 1.0 - 2.0 * q))
    return ImpactResult(vb - q * slip, -e * vn, omega - 2.0 * q * slip / r, False, jac)
