"""CAN logs offline: log synthesis from run tables, log replay through the live service, the HIL plant on a bus."""
