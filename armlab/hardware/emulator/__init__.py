"""Virtual servos behind a pseudo-terminal, moved by the simulated plant: a serial client
(the lab's own bus, or another program) cannot tell them from real ones."""
