"""The onboard sensor: the reduction of the network description to onboard tables (build time), the one pure step,
warnings and time to limit, and the VirtualSensor that holds them. Imports the physics and the description, never
the CAN service or ``tools``."""
