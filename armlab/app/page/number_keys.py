"""Number fields that take what a person types, or say what they cannot take.

A number field on viser's page (Mantine's NumberInput) drops, without a word, every key
but digits, one decimal point and a leading minus: a teacher typing "1e9" saw "19" and
the lab applied 19. :func:`install` sends each page a small script
(:func:`armlab.app.viser_ext.page_scripts.number_keys_script`) that stops such a key
before the field drops it:

- "e" after a number starts an exponent, shown under the field (:data:`EXPONENT`:
  "1e9 = 1000000000: Enter sets it"); Enter or Tab types the value into the field in
  plain digits (the focus stays: the field would clamp on leaving before the lab heard
  the value, and the lab's message names what it applies), and so does leaving the
  field; Backspace takes the exponent back, Esc drops it;
- any other key the field cannot take is named under it (:data:`SAYS`) for
  :data:`SHOW_MS` ms, and the field keeps what it held.

What the field then sends meets the page's one rule for numbers
(:func:`armlab.app.page.inputs.typed_value`): 1e9 for Kp is applied as 200, and the page
is told so.
"""

from __future__ import annotations

import viser

from armlab.app.viser_ext.page_js import run_javascript
from armlab.app.viser_ext.page_scripts import number_keys_script

#: The line under a number field after a key it cannot take (``{key}``: that key).
SAYS = "“{key}” cannot be typed in a number: digits, one point, a minus, an e (1e9)"
#: The line under a number field while an exponent is typed.
EXPONENT = "{typed} = {value}: Enter sets it, Esc drops it"
#: ms the line stays.
SHOW_MS = 5000


def send(client: viser.ClientHandle) -> None:
    """Run the script in ``client``'s page (nothing on a viser without the message)."""
    run_javascript(client, number_keys_script(says=SAYS, exponent=EXPONENT, show_ms=SHOW_MS),
                   name="number keys")


def install(server: viser.ViserServer) -> None:
    """Send the script to every page that connects to ``server`` from now on."""
    server.on_client_connect(send)
