"""The one door to viser's insides: every private viser name the lab uses, and every
script or style aimed at viser's page structure, lives in this package (each module
says what in viser it relies on, and the viser version it was seen in).

:func:`check_hooks` checks each hook against the installed viser; :func:`require_hooks`
(called when a lab starts) refuses to start when a hook the lab's security needs is
missing (the gate fails closed) and logs a warning for any other.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass

#: the viser release every hook here was seen working in
SEEN_IN = "1.1.1"


@dataclass(frozen=True)
class Hook:
    """One place the lab reaches into viser.

    Attributes:
        name: what the lab uses it for.
        module: the module of this package holding it.
        security: the lab must not start without it (the gate, the checks after it).
    """

    name: str
    module: str
    security: bool

    def missing(self) -> list[str]:
        """What of viser this hook needs and does not find (empty: in place)."""
        import importlib

        try:
            check: Callable[[], list[str]] = importlib.import_module(
                f"{__name__}.{self.module}").missing
            return check()
        except Exception as exc:  # a viser that moved a module: that is what is missing
            return [f"{type(exc).__name__}: {exc}"]


HOOKS = (
    Hook("the gate in front of the websocket (token, Origin, unreadable messages)",
         "websocket", security=True),
    Hook("the screens of what pages send (value checks, classroom roles)", "dispatch",
         security=True),
    Hook("viser's message classes", "messages", security=False),
    Hook("scripts and styles run in a page (E-STOP first, panels, text sizes, passcode "
         "masked)", "page_js", security=False),
    Hook("pages' connections and queues (one page's own updates, the classroom's stream)",
         "clients", security=False),
    Hook("GUI elements' and scene nodes' ids and scopes", "handles", security=False),
    Hook("a page's camera record", "camera", security=False),
    Hook("the robot's scene nodes (ViserUrdf)", "urdf", security=False),
    Hook("work-arounds (message buffer race, cheap pose writes)", "fixes", security=False),
    Hook("a size limit on uploaded files (Open run)", "uploads", security=False),
)


@dataclass(frozen=True)
class MissingHook:
    """A hook that is not in place: which, and what of viser it did not find."""

    hook: Hook
    what: list[str]

    def __str__(self) -> str:
        return f"{self.hook.name} [viser_ext.{self.hook.module}]: {'; '.join(self.what)}"


class HooksMissing(RuntimeError):
    """The installed viser lacks what a security hook needs: the lab does not start."""


def viser_version() -> str:
    """The installed viser's version ("unknown" if it does not say)."""
    import viser

    return str(getattr(viser, "__version__", "unknown"))


def check_hooks() -> list[MissingHook]:
    """Every hook of :data:`HOOKS` not in place against the installed viser (empty: all)."""
    out = []
    for hook in HOOKS:
        what = hook.missing()
        if what:
            out.append(MissingHook(hook, what))
    return out


def require_hooks(*, warn: Callable[[str], None] | None = None) -> None:
    """Check every hook: log one warning line per missing non-security hook (that part of
    the lab degrades), and refuse a missing security hook.

    Raises:
        HooksMissing: one message naming the installed viser's version and each missing
            security hook with what it did not find.
    """
    warn = warn or (lambda line: print(line, file=sys.stderr, flush=True))
    lacking = check_hooks()
    fatal = [m for m in lacking if m.hook.security]
    for m in lacking:
        if not m.hook.security:
            warn(f"armlab: warning: viser {viser_version()}: {m} (that part works less well)")
    if fatal:
        version = viser_version()
        advice = "" if version == SEEN_IN else f" Install viser=={SEEN_IN}, which it was made for."
        raise HooksMissing(
            f"not starting: the installed viser {version} lacks what the lab needs for "
            + " | ".join(str(m) for m in fatal)
            + ". Without it the lab cannot check who opens its websocket." + advice)
