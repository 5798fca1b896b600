"""Shared by the twin/scale tests: a yellowfish with an identification uncertainty block written by
hand (what `twin identify` stores: coordinates ln|θ| of log-normal coefficients, their mean and
covariance), wide enough that its bands are metres, not millimetres."""
import math
from dataclasses import replace

import numpy as np

import twin.vessel as vessel_mod

SIGMA = {"Xu": 0.2, "Xuu": 0.15, "Nr": 0.2, "Nrr": 0.15, "thrust_gain": 0.05}
CORRELATION = {("Xu", "Xuu"): -0.6, ("Nr", "Nrr"): -0.5}


def identified() -> vessel_mod.Vessel:
    v = vessel_mod.load("yellowfish")
    values = {"Xu": v.damping.Xu, "Xuu": v.damping.Xuu, "Nr": v.damping.Nr, "Nrr": v.damping.Nrr,
              "thrust_gain": 0.5 * (v.thrusters.gain_left + v.thrusters.gain_right)}
    names = list(SIGMA)
    cov = np.diag([SIGMA[n] ** 2 for n in names])
    for (a, b), rho in CORRELATION.items():
        i, j = names.index(a), names.index(b)
        cov[i, j] = cov[j, i] = rho * SIGMA[a] * SIGMA[b]
    block = {"coordinates": [{"name": n, "log": True, "sign": math.copysign(1.0, values[n])} for n in names],
             "mean": [math.log(abs(values[n])) for n in names], "covariance": cov.tolist(), "source": "by hand"}
    return replace(v, uncertainty=block)
