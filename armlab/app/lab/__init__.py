"""The served lab: one viser server with its lessons, its room and its gate
(``server.py``: ``Lab``, ``ServeOptions``), and the JupyterHub launcher that starts it
behind jupyter-server-proxy (``jupyter.py``)."""
