"""Servos: protocol 1.0, the serial bus, the simulated servo and plant, the emulator, backends."""
