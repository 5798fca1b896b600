"""Identification: synthetic datasets with known truth, then (later) grey-box and simulation-based fits."""
