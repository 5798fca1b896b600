"""Seed 003: identification by self-oscillations (IS-O, relay with hysteresis, Table I) and
the I-PD dynamic-positioning controller tuned from it (eqs. 9-11) (references.SEEDS["003"])."""
