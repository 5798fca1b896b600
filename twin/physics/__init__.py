"""Pure-function 3-DOF marine physics (surge, sway, yaw), shared by the MuJoCo
callbacks and the analytic model. Nothing here imports mujoco.

Conventions (Fossen; [Yellowfish-TR §III]): η = [x, y, ψ] in NED (x north, y east,
ψ from north towards east), ν = [u, v, r] in the body frame FRD (x forward,
y starboard, z down). Forces τ = [X, Y, N] in N, N, N·m.
"""
