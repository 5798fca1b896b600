"""Identification: from recordings to a vessel description the twin loads. identify.py is the
loop (calibrate each log, fit by simulation, judge on runs left out); greybox/ is the
least-squares thruster identification [Morel-2024] and relay/ the identification by
self-oscillation with the I-PD controller tuned from it [Relay-ISO]."""
