"""Servos: the wire and its protocols, the servos' tables, the simulation, the backends the
controller drives, and the emulator."""
