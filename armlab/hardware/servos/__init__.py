"""What every family's servo facts share: a control table's items and their encoding
(``control_table.py``), datasheet units and wire timing (``servo_spec.py``). Each family's
tables are its folder's ``table.py`` (:mod:`armlab.hardware.families`)."""
