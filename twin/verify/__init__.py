"""Checks of the twin against independent references: the engine against the analytic
3-DOF model, term by term (crosscheck), and the vessel against its source's formulas and
tables (validate)."""
