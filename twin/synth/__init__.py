"""Synthetic recordings with a known truth: the twin driven through identification
manoeuvres [Morel-2024 §6.1], its sensors logged with noise, effects injected by name."""
