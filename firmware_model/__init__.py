"""What runs onboard: the physics the sensor needs, the reduced thermal network and its fixed step,
warnings, and the CAN service. Depends on numpy and the standard library only."""
__version__ = "0.1.0"
