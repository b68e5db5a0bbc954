"""The classroom (``armlab serve --classroom``): roles and the passcode (``roles.py``, the
page's gate ``gate.py``), the room's pages, the seats handing out every student's private
arm, hand and quadruped (``sandboxes.py``; the robots themselves run in
:mod:`armlab.app.workers`), the muting of the shared stream and the
presenter's overview. Its engineering (processes, batching, costs): docs/classroom.md."""
