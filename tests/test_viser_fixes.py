"""app.viser_fixes: a GUI call from a callback thread that meets viser's waiter race
(``deque mutated during iteration`` from the direct ``asyncio.Event.set``) still reaches
the page, and the lab's code never sees the error. The race itself needs a busy machine;
here the buffer's event raises it on demand, once."""

from __future__ import annotations

import viser
from _helpers import client_of

from app import viser_fixes


def test_a_gui_call_that_meets_the_race_reaches_the_page():
    viser_fixes.install()
    viser_fixes.install()  # twice is once
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        with client_of(server) as page:
            (client,) = server.get_clients().values()
            event = client._websock_connection.get_message_buffer().message_event
            calls: list[str] = []
            set_event = event.set

            def racing_set() -> None:  # the first set (the direct one) meets the race
                calls.append("set")
                if len(calls) == 1:
                    raise RuntimeError("deque mutated during iteration")
                set_event()

            event.set = racing_set  # the sender waits on this very event
            handle = client.gui.add_markdown("after the race")  # must not raise
            page.wait_for(lambda: any(e.props.get("_markdown") == "after the race"
                                      for e in list(page.gui.values())),
                          what="the markdown that met the race")
            assert len(calls) >= 2  # raced, then woke the sender through the loop
            handle.remove()
    finally:
        server.stop()
