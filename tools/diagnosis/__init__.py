"""Sim-to-real gap diagnosis: prepare, fit, decide, report; the withheld-effect benchmark; model backends."""
