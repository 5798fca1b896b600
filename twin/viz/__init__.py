"""Visualisation: rerun recordings of runs (rerun_log), report figures and tables (report), the
relay identification's figures, and result pages written by the study scripts (pages)."""
