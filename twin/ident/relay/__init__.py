"""Identification by self-oscillations (IS-O, relay with hysteresis, [Relay-ISO] Table I) and the
I-PD dynamic-positioning controller tuned from it ([Relay-ISO] eqs. 9-11)."""
