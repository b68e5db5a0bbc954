"""Virtual servos behind a pseudo-terminal, moved by the simulated plant: a serial client
(the lab's own bus, or another program) cannot tell them from real ones. What every
family's emulator shares; each family's servos are its folder's ``emulator.py``
(:mod:`armlab.hardware.families`)."""
