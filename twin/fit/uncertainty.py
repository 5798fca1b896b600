"""What identification leaves uncertain, carried in the vessel file, and twins drawn from it.

A maximum a posteriori fit (simfit) ends with the covariance of its coordinates (ln|θ| for a
log-normal coefficient, θ otherwise). The vessel file keeps the coordinates, their values and
that covariance (`Vessel.uncertainty`); a coefficient the recordings did not pin down carries its
belief's variance and no correlation, since the data said nothing about it. `draw` turns the block
into twins: coordinates ~ N(mean, covariance), put back through the same coefficients, so a
log-normal coefficient keeps its sign. Draws that leave the vessel unphysical (damping that
stops dissipating, M not positive-definite) are redrawn and counted.
"""
from __future__ import annotations

import numpy as np

from ..effects import coefficients
from ..effects.quantity import log_magnitude
from ..errors import TwinError
from ..vessel import Vessel, check


def block(fit, coordinates, free: np.ndarray, source: str = "") -> dict:
    """The uncertainty block of a MAP fit (simfit.FitResult with its coordinates and which of them
    the data pinned down)."""
    obj, x = fit.objective, fit.x
    mean = x * obj.scale
    cov = np.array(fit.covariance, float) if fit.covariance is not None else np.diag(
        [c.belief.sigma ** 2 for c in coordinates])
    for i, c in enumerate(coordinates):
        if not free[i]:
            cov[i, :] = cov[:, i] = 0.0
            cov[i, i] = c.belief.sigma ** 2
    cov = 0.5 * (cov + cov.T)
    return {"coordinates": [{"name": c.name, "log": c.log, "sign": float(np.sign(c.prior_value) or 1.0)}
                            for c in coordinates],
            "mean": [float(v) for v in mean], "covariance": [[float(v) for v in row] for row in cov],
            **({"source": source} if source else {})}


def _put(vessel: Vessel, coordinate: dict, value: float) -> Vessel:
    q = coefficients(vessel)[coordinate["name"]]
    if coordinate["log"]:
        return q.put(vessel, coordinate["sign"] * float(np.exp(value)))
    return q.put(vessel, float(value))


def check_drawable(vessel: Vessel) -> None:
    """TwinError (one line) unless the vessel's uncertainty block names coefficients this vessel has,
    one for each entry of its mean (checked before a command's work: a block edited by hand would
    otherwise fail at its first draw)."""
    u = vessel.uncertainty
    if not u:
        raise TwinError(f"vessel '{vessel.name}' carries no identification uncertainty (identify it first)")
    known = coefficients(vessel)
    unknown = [c["name"] for c in u.get("coordinates", []) if c["name"] not in known]
    if unknown:
        raise TwinError(f"vessel '{vessel.name}': uncertainty.coordinates name{'s' if len(unknown) > 1 else ''} "
                        f"{', '.join(map(repr, unknown))}, which {'are' if len(unknown) > 1 else 'is'} no coefficient "
                        f"of this vessel (known: {', '.join(sorted(known))})")
    n = len(u.get("coordinates", []))
    if len(u.get("mean", [])) != n or np.shape(u.get("covariance", [])) != (n, n):
        raise TwinError(f"vessel '{vessel.name}': the uncertainty block's mean and covariance must match its {n} "
                        "coordinates")


def draw(vessel: Vessel, n: int, rng: np.random.Generator, max_tries: int = 20) -> tuple[list[Vessel], int]:
    """n twins drawn from the vessel's uncertainty block, and how many draws were rejected as
    unphysical. TwinError without a block, or with one that names no coefficient of the vessel."""
    check_drawable(vessel)
    u = vessel.uncertainty
    mean, cov = np.asarray(u["mean"], float), np.asarray(u["covariance"], float)
    # a covariance a little short of positive semi-definite (rounding in the file) still draws
    w, V = np.linalg.eigh(0.5 * (cov + cov.T))
    root = V * np.sqrt(np.clip(w, 0.0, None))
    out, rejected = [], 0
    while len(out) < n:
        x = mean + root @ rng.standard_normal(len(mean))
        v = vessel
        for c, value in zip(u["coordinates"], x):
            v = _put(v, c, value)
        try:
            check(v)
        except TwinError:
            rejected += 1
            if rejected > max_tries * max(n, 1):
                raise TwinError(f"vessel '{vessel.name}': its uncertainty draws are unphysical again and again") from None
            continue
        out.append(v)
    return out, rejected


__all__ = ["block", "check_drawable", "draw", "log_magnitude"]
