"""Identification: from recordings to a vessel description the twin loads. identify.py
is the loop (calibrate each log, fit by simulation, judge on runs left out); seed004/
and seed003/ hold the two seeds' own methods."""
