"""The classroom (``armlab serve --classroom``): roles and the passcode, the room's pages,
every student's private arm, hand and quadruped (seats, the batched simulations on one clock,
the worker process they run in and its proxies), the muting of the shared stream and the
presenter's overview. Its engineering (processes, batching, costs): docs/classroom.md."""
