"""Servos on the wire, whatever their family: the serial bus (one transaction at a time;
its port, errors, group reads and items by name) and the scan that finds servos on a
port. Each family's packets are its folder's ``packets.py``
(:mod:`armlab.hardware.families`)."""
