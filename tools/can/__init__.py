"""CAN on the tools side: log synthesis from run tables (``logsynth``), the HIL plant on a bus (``hil``), the live
sensor on a bus (``live``) and the bus options and signal handling the CAN subcommands share (``bus``)."""
