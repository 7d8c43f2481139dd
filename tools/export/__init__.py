"""Deployment bundles of the onboard sensor: C sources for an ECU (export-c)."""
