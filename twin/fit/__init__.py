"""Fitting by simulation, the public core every identification and diagnosis uses:
free runs of the twin from measured states on the batch engine (windows), the
objective and its covariance (objective), the simulation fit of a vessel's parameters
(simfit), R² and MAE (metrics), judging any model by its predictions (evaluate), and a
log's own sensor calibration (calibrate)."""
