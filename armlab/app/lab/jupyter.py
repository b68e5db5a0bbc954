"""armlab inside JupyterLab (and so JupyterHub): the jupyter-server-proxy entry point.

With ``pip install armlab[hub]`` in the user image, every user's Jupyter server offers an
"armlab" tile in the JupyterLab launcher. The tile opens
``/user/NAME/armlab/index.html?armlab_token=TOKEN`` in a new tab (not ``?token=``:
that name is Jupyter's own login token); jupyter-server-proxy starts
``armlab serve`` on a free loopback port the first time that address is asked for, waits
until it answers, and forwards everything under ``/user/NAME/armlab/`` to it (the page
and its websocket) with the prefix cut off. The lab itself runs unchanged, one per user
server: the hub spawns and scales the servers.

Who gets in (two locks, both needed):

- **Jupyter's own login** guards every address under ``/user/NAME/``: only the server's
  owner (or whom the hub lets in) reaches the proxy (for a browser logged in by cookie,
  Jupyter also checks a websocket's ``Origin``; for a request with a Jupyter token it
  does not, and the lab's gate below still does).
- **armlab's gate** (:mod:`armlab.app.classroom.gate`) still stands in front of the lab's websocket,
  because the lab's loopback port is open to every process of the machine, and on a
  shared node that means other users' processes: they do not pass through Jupyter. The
  token is random for each start of the Jupyter server (or ``ARMLAB_TOKEN`` of the
  server's environment), reaches ``armlab serve`` through its environment (never its
  command line, which every user of the machine can read with ``ps``) and the browser
  through the launcher's address, which only the logged-in owner sees. The page served
  for that address sets the token cookie; its path is the page's own folder (the cookie
  has no ``Path``), ``/user/NAME/armlab``, so it goes to this lab only, not to the rest
  of the hub.

The proxy passes the browser's ``Host`` and ``Origin`` headers on unchanged, so the
gate's Origin check (the scheme and the ``Host`` the request was made to) holds as it
does without the proxy: no extra trust in the proxy is needed and none is granted.

Why ``index.html`` in the address: viser's page opens its websocket on its own address
with the query and one trailing slash removed. From ``/user/NAME/armlab/`` that is
``/user/NAME/armlab``, which Jupyter answers with a redirect to add the slash (a
websocket cannot follow it). From ``/user/NAME/armlab/index.html`` it is that same
address, which the proxy forwards to the lab (viser's websocket accepts any path). A page
asked for at ``/user/NAME/armlab/`` (a typed or bookmarked address) is sent on to
``index.html`` by the gate (:meth:`armlab.app.classroom.gate.Gate.wrap`).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any

from armlab.app.classroom.gate import COOKIE, check_token, new_token

#: the environment variable holding the token (read by ``armlab serve`` as --token's default)
TOKEN_ENV = "ARMLAB_TOKEN"
#: the proxy's name: the lab lives at ``<jupyter base url>/armlab/``
NAME = "armlab"
#: s: how long the proxy waits for a starting lab to answer (a loaded server)
START_TIMEOUT = 60.0
ICON = Path(__file__).with_name("armlab_icon.svg")


def launcher_path(token: str) -> str:
    """The launcher tile's address below the Jupyter server's base URL."""
    return f"{NAME}/index.html?{COOKIE}={token}"


def setup_armlab() -> dict[str, Any]:
    """The ``jupyter_serverproxy_servers`` entry point: how jupyter-server-proxy starts
    and shows the lab (called once per start of the Jupyter server)."""
    token = check_token(os.environ.get(TOKEN_ENV) or new_token())
    return {
        # jupyter-server-proxy picks a free port and puts it in for {port}
        "command": [sys.executable, "-m", "armlab.app", "serve", "--http-port", "{port}"],
        "environment": {TOKEN_ENV: token},
        "timeout": START_TIMEOUT,
        "absolute_url": False,  # the lab sees "/...", the prefix cut off
        "new_browser_tab": True,  # the 3D view wants the whole tab
        "launcher_entry": {
            "enabled": True,
            "title": "armlab",
            "icon_path": str(ICON),
            "path_info": launcher_path(token),
        },
    }
