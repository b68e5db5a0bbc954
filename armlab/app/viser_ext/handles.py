"""What viser keeps private about its GUI elements, scene nodes and their scopes.

relies on: a handle's ``_impl`` (``uuid``, ``removed``, ``props``, ``gui_api`` / ``api``),
``_queue_update``; a GuiApi's / SceneApi's ``_owner``, ``_gui_input_handle_from_uuid``,
``_handle_from_node_name``, ``_owner_id``; seen in viser 1.1.1
"""

from __future__ import annotations

from typing import Any

import viser

from armlab.app.viser_ext.probe import assigned_in


def missing() -> list[str]:
    """What of the above this viser lacks (checked on its classes' code)."""
    from viser import _gui_api, _gui_handles, _scene_api

    need = [(_gui_api.GuiApi, ("_owner", "_gui_input_handle_from_uuid", "_websock_interface")),
            (_scene_api.SceneApi, ("_owner", "_handle_from_node_name", "_owner_id")),
            (_gui_handles._GuiHandle, ("_impl",))]
    out = [f"{cls.__name__}.{name}" for cls, names in need for name in names
           if not assigned_in(cls, name)]
    if not hasattr(_gui_handles._GuiInputHandle, "_queue_update"):
        out.append("_GuiInputHandle._queue_update")
    return out


def uuid_of(handle: Any) -> str:
    """The id viser's messages name GUI element ``handle`` by."""
    return handle._impl.uuid


def is_removed(handle: Any) -> bool:
    """Whether GUI element or scene node ``handle`` has been removed."""
    return bool(handle._impl.removed)


def owner_of(handle: Any) -> viser.ViserServer | viser.ClientHandle:
    """The server (an element every page shows) or the page (one page's own) that a GUI
    element or scene node belongs to."""
    impl = handle._impl
    api = impl.gui_api if hasattr(impl, "gui_api") else impl.api
    return api._owner


def scene_scope(handle: Any) -> str:
    """The scope id viser's scene messages carry for scene node ``handle`` ("" the
    server's scene, else the page's client id)."""
    return handle._impl.api._owner_id


def scene_scope_of(scene: Any) -> str:
    """The scope id of a server's or a page's ``scene`` (see :func:`scene_scope`)."""
    return scene._owner_id


def is_gui(handle: Any) -> bool:
    """Whether ``handle`` is a GUI element (else a scene node)."""
    return hasattr(handle._impl, "gui_api")


def scene_nodes(scene: Any) -> dict[str, Any]:
    """Node name -> handle of every node of ``scene`` (viser keeps no public index; the
    dict is viser's own: read it, do not change it)."""
    return scene._handle_from_node_name


def gui_inputs(gui: Any) -> dict[str, Any]:
    """uuid -> handle of every input of ``gui`` (a server's or a page's; viser's own dict:
    read it, do not change it)."""
    return gui._gui_input_handle_from_uuid


def set_prop_uncast(handle: Any, name: str, value: Any) -> None:
    """Set GUI element ``handle``'s property ``name`` to ``value`` as it is and send it to
    its pages (``handle.name = value`` would cast it to viser's hinted type first).

    Raises:
        RuntimeError: the element has been removed (as viser's own assignment)."""
    impl = handle._impl
    if impl.removed:
        raise RuntimeError(f"Cannot assign to {name!r} on a removed {type(handle).__name__}.")
    setattr(impl.props, name, value)
    handle._queue_update(name, value)
