"""viser's own message classes the lab sends or recognises (``viser._messages`` is
private: another release may move them; :func:`missing` says which are gone).

relies on: viser._messages.{GuiUpdateMessage, SceneNodeUpdateMessage, SetPositionMessage,
SetOrientationMessage, SetCameraPositionMessage, SetCameraLookAtMessage,
RunJavascriptMessage}; seen in viser 1.1.1
"""

from __future__ import annotations

from typing import Any

from viser import _messages

NAMES = ("GuiUpdateMessage", "SceneNodeUpdateMessage", "SetPositionMessage",
         "SetOrientationMessage", "SetCameraPositionMessage", "SetCameraLookAtMessage",
         "RunJavascriptMessage")

#: ``GuiUpdateMessage(uuid, updates)``: a GUI element's properties (a page sends its
#: inputs' values with it too)
GuiUpdateMessage: Any = getattr(_messages, "GuiUpdateMessage", None)
#: ``SceneNodeUpdateMessage(name, updates, owner=)``: a scene node's properties
SceneNodeUpdateMessage: Any = getattr(_messages, "SceneNodeUpdateMessage", None)
#: a scene node's position / orientation
SetPositionMessage: Any = getattr(_messages, "SetPositionMessage", None)
SetOrientationMessage: Any = getattr(_messages, "SetOrientationMessage", None)
#: a page's camera position / look-at point
SetCameraPositionMessage: Any = getattr(_messages, "SetCameraPositionMessage", None)
SetCameraLookAtMessage: Any = getattr(_messages, "SetCameraLookAtMessage", None)
#: ``RunJavascriptMessage(source=)``: the page runs ``source`` (how viser loads Plotly)
RunJavascriptMessage: Any = getattr(_messages, "RunJavascriptMessage", None)


def missing() -> list[str]:
    """The message classes of :data:`NAMES` this viser lacks."""
    return [f"viser._messages.{name}" for name in NAMES if globals()[name] is None]


def is_gui_update(message: Any) -> bool:
    """Whether ``message`` (from a page) is an update of a GUI element's properties."""
    return GuiUpdateMessage is not None and isinstance(message, GuiUpdateMessage)
