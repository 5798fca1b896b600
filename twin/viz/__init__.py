"""Visualisation: rerun recordings of runs (rerun_log), report figures and tables (report),
seed 003's IS-O and I-PD figures (seed003)."""
