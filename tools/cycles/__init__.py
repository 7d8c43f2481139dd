"""Synthetic named drive cycles (modelled on the thesis load cases) and their plots."""
