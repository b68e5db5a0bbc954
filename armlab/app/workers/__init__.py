"""A class's private robots, in a process of their own: the worker (``worker.py``) and its
link (``worker_link.py``), the server's handle on it (``worker_process.py``), the arms,
hands and quadrupeds it steps (``class_arms.py``, ``class_hands.py``,
``class_quadrupeds.py``) and the lesson's view of a remote hand or quadruped
(``remote_hand.py``, ``remote_gait.py``)."""
