"""Diagnosis: where twin and recording disagree, which physics is missing, and the amended twin."""
