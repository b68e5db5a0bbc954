"""Gain sliders and presets of the compliance lesson.

Each slider is a :class:`armlab.app.page.inputs.GuardedNumber`: a typed value that is not a
finite number inside the slider's range is refused with a notification and the
slider goes back. A good value builds a new, validated :class:`Params` and hands
it to ``apply`` (which swaps it into the control loop at its next period). A
preset sets every slider and applies the whole preset once.

viser calls an input's callbacks when Python sets its value too. Every callback
here compares with :attr:`GainControls.params` (updated before any input is
shown) and does nothing when they agree, so showing the parameters on the
inputs never applies anything again and needs no re-entry flag.

:func:`apply_gains` is the ``apply`` every arm lesson gives it: the parameters go to
the control loop, which holds them to the lab's one rule on gains
(:func:`armlab.control.params.check_gains`: unstable gains refused on real servos), and
the warning line under the status shows what that rule found.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import fields, replace

import viser

from armlab.app.lessons._common import warning_html
from armlab.app.page.inputs import GuardedNumber, notify
from armlab.control.laws import LAWS as LAW_REGISTRY
from armlab.control.loop import ControlLoop
from armlab.control.params import LAWS, PARAM_SPECS, PRESETS, GainCheck, Params

#: Slider value shown = SI value × scale (the period is shown in ms).
DISPLAY_SCALE = {"period": 1000.0}
DISPLAY_UNIT = {"period": "ms"}
LAW_LABELS = {key: law.label for key, law in LAW_REGISTRY.items()}
CUSTOM = "(custom)"


def slider_label(name: str) -> str:
    """"Kp (1/s²)", "period (ms)"..."""
    spec = PARAM_SPECS[name]
    unit = DISPLAY_UNIT.get(name, spec.unit)
    return f"{spec.label} ({unit})" if unit else spec.label


class GainControls:
    """Sliders for every numeric field of :class:`Params`, the compliance and feed-forward
    switches, the law and the preset picker.

    Args:
        gui: where to add them (inside the caller's tab/folder context).
        params: initial parameters.
        apply: called with a new :class:`Params`; raises ValueError to refuse it (its
            message is shown and the inputs go back).

    Attributes:
        params: the parameters last accepted.
        sliders: field name -> GuardedNumber.
    """

    def __init__(self, gui: viser.GuiApi, params: Params, *,
                 apply: Callable[[Params], None]) -> None:
        self._apply = apply
        self._lock = threading.RLock()
        self.params = params
        self.preset = gui.add_dropdown("Preset", (*PRESETS, CUSTOM),
                                       initial_value=_preset_of(params),
                                       hint="Gains from the thesis or the lab's damped default")
        self.compliance = gui.add_checkbox("Compliance on", params.compliance,
                                           hint="Off: plain PD loop (eq. 2.20); on: the arm "
                                                "yields to outside torque (eq. 2.6/2.7)")
        self.feedforward = gui.add_checkbox(
            "Feed-forward θ̈_cmd", params.feedforward,
            hint="Not in the thesis: adds the commanded acceleration to θ̈_ref so the "
                 "reference follows the moving command; off = the thesis's loop (eq. 2.3 "
                 "lags a moving command). On in the lab's default, off in the thesis presets")
        self.law = gui.add_dropdown("Law", tuple(LAW_LABELS[k] for k in LAWS),
                                    initial_value=LAW_LABELS[params.law],
                                    hint="2.6 offsets the reference by θ_env; 2.26 (as printed "
                                         "in the thesis) multiplies the offsets by K_env, "
                                         "D_env, M_env")
        self.sliders: dict[str, GuardedNumber] = {}
        for f in fields(Params):
            if f.name not in PARAM_SPECS:
                continue
            spec = PARAM_SPECS[f.name]
            k = DISPLAY_SCALE.get(f.name, 1.0)
            handle = gui.add_slider(slider_label(f.name), min=spec.min * k, max=spec.max * k,
                                    step=spec.step * k,
                                    initial_value=float(getattr(params, f.name)) * k,
                                    hint=spec.help)
            self.sliders[f.name] = GuardedNumber(
                handle, name=spec.label, lo=spec.min * k, hi=spec.max * k,
                apply=lambda v, name=f.name, k=k: self._set_field(name, v / k), lock=self._lock)  # type: ignore[misc]  # mypy cannot infer a lambda with default arguments

        @self.preset.on_update
        def _(event: viser.GuiEvent) -> None:
            name = str(self.preset.value)
            if name in PRESETS and PRESETS[name] != self.params:
                try:
                    self.set_params(PRESETS[name])
                except ValueError as exc:
                    notify(event.client, "Preset refused", str(exc))

        @self.compliance.on_update
        def _(event: viser.GuiEvent) -> None:
            self._set_other(event, compliance=bool(self.compliance.value))

        @self.feedforward.on_update
        def _(event: viser.GuiEvent) -> None:
            self._set_other(event, feedforward=bool(self.feedforward.value))

        @self.law.on_update
        def _(event: viser.GuiEvent) -> None:
            law = next(k for k, v in LAW_LABELS.items() if v == self.law.value)
            self._set_other(event, law=law)

    # -- changes -----------------------------------------------------------------

    def _set_field(self, name: str, value: float) -> None:
        """A slider moved (value in SI); raises ValueError to refuse it."""
        with self._lock:
            self._commit(replace(self.params, **{name: value}))  # type: ignore[arg-type]  # replace(): each name a field of Params, its value checked there; validates

    def _set_other(self, event: viser.GuiEvent, **changes: object) -> None:
        with self._lock:
            try:
                self._commit(replace(self.params, **changes))  # type: ignore[arg-type]  # replace(): each name a field of Params, its value checked there
            except ValueError as exc:
                notify(event.client, "Change refused", str(exc))
                self._show(self.params)

    def _commit(self, new: Params) -> None:
        """Apply ``new`` (unless it is in force) and show which preset it is."""
        if new == self.params:
            return
        self._apply(new)
        self.params = new
        self.preset.value = _preset_of(new)  # type: ignore[misc]  # viser: value's setter is apart from its getter, mypy sees none

    def set_params(self, params: Params) -> None:
        """Apply ``params`` at once (a preset) and show them on every page.

        Raises:
            ValueError: when ``apply`` refuses them (nothing changes then).
        """
        with self._lock:
            if params != self.params:
                self._apply(params)
                self.params = params
            self._show(params)

    def _show(self, params: Params) -> None:
        """Put every input at ``params`` (the parameters in force: their callbacks then
        find nothing to apply)."""
        for name, g in self.sliders.items():
            v = float(getattr(params, name)) * DISPLAY_SCALE.get(name, 1.0)
            g.value = v  # first, so the slider's callback sees no change
            g.handle.value = v
        self.compliance.value = params.compliance  # type: ignore[misc]  # viser: value's setter is apart from its getter, mypy sees none
        self.feedforward.value = params.feedforward  # type: ignore[misc]  # viser: value's setter is apart from its getter, mypy sees none
        self.law.value = LAW_LABELS[params.law]  # type: ignore[misc]  # viser: value's setter is apart from its getter, mypy sees none
        self.preset.value = _preset_of(params)  # type: ignore[misc]  # viser: value's setter is apart from its getter, mypy sees none


def apply_gains(loop: ControlLoop, params: Params, *, warning: viser.GuiHtmlHandle) -> None:
    """Swap ``params`` into ``loop`` (at its next period) and show what the loop's rule on
    gains found in ``warning``.

    Raises:
        ValueError: refused by the rule (unstable gains on real servos; nothing changes then).
    """
    show_gain_warning(warning, loop.set_params(params))


def show_gain_warning(warning: viser.GuiHtmlHandle, gains: GainCheck) -> None:
    """Show the rule's warning on ``gains`` in ``warning`` (hidden when there is none): red
    for unstable gains, amber for a caution."""
    if gains.warning is None:
        warning.visible = False
        return
    color = "#b00020" if gains.unstable else "#a15c00"
    head = "Unstable gains" if gains.unstable else "Check the gains"
    warning.content = warning_html(head, gains.warning, color=color)
    warning.visible = True


def _preset_of(params: Params) -> str:
    for name, p in PRESETS.items():
        if p == params:
            return name
    return CUSTOM
