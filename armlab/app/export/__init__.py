"""A run exported as one self-contained HTML page (``html.py``): its sections and figures
(``sections.py``), its charts drawn as SVG (``charts.py``) and the replay viewer's script
and style (``viewer.py``)."""
