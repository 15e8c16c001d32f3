"""tactile_force.firmware_bridge: USB sensors, HID reference scale, OAK accelerator (each imported lazily)."""
