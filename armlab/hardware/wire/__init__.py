"""Servos on the wire: the Dynamixel protocol 1.0 and 2.0 packets, the serial bus (one
transaction at a time) and the scan that finds servos on a port."""
