"""The servos' own facts: control tables and datasheet numbers of the AX-12A and RX-24F
(protocol 1.0) and of the X-series (protocol 2.0)."""
