"""The QEMU harness that runs a real Linux vcan0 for the SocketCAN tests (this kernel has no CAN)."""
