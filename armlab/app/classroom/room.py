"""The classroom's pages (``armlab serve --classroom``): roles, "My arm", the join QR code.

Every page that joins gets, of its own (``client.gui``, seen by that page only): a
role line, a "Passcode" field (masked as a password field), a "Your name" field and a
"View" switch between
"Follow the teacher" (the shared arm, read-only: :class:`armlab.app.classroom.roles.Roles`
refuses a follower's changes) and "My arm" (a private copy of the open lesson on the
page, driving the student's own simulated arm: :mod:`armlab.app.classroom.sandboxes`). While a page
shows its own arm, the shared lesson's panel is hidden on that page only, the
private arm's scene nodes, named as the shared ones, are drawn there in their place,
and the shared lesson's updates are held back from it (:mod:`armlab.app.classroom.muting`: the
server
does not serialise a stream the page does not show).
"""

from __future__ import annotations

import dataclasses
import secrets
import sys
import threading
from dataclasses import dataclass, replace
from typing import Any, Protocol

import numpy as np
import viser

from armlab.app.classroom.gate import Gate
from armlab.app.classroom.muting import SharedStream
from armlab.app.classroom.overview import (
    GHOST_OFFSET,
    GHOST_RGBA,
    ClassOverview,
    StudentRow,
)
from armlab.app.classroom.private_page import Page
from armlab.app.classroom.roles import (
    Roles,
    address_of,
    loopback_warning,
    new_passcode,
    presenter_link_code,
    qr_svg,
)
from armlab.app.classroom.sandboxes import ClassFull, Sandboxes
from armlab.app.lessons import Figures, Lesson, LessonContext, LessonHandle
from armlab.app.lessons._common import esc, remove_quietly, warning_html
from armlab.app.lessons.catalog import all_lessons
from armlab.app.lessons.challenge_panel import (
    ChallengeDesk,
    MyChallenge,
    figures_of,
    results_of,
    start_run,
    tags_of,
)
from armlab.app.page import camera, theme
from armlab.app.page.arm_view import ArmView
from armlab.app.page.inputs import UpdateScreen, notify
from armlab.app.page.publisher import FrameThread
from armlab.app.viser_ext.clients import queue
from armlab.app.viser_ext.handles import uuid_of
from armlab.app.viser_ext.messages import GuiUpdateMessage
from armlab.app.viser_ext.page_js import ask_item, mask_text_input
from armlab.control import collector
from armlab.control.challenges import RunLog, gradebook_bytes, utc_now

#: the role line of a page that follows the teacher
FOLLOWER_TEXT = ("**Following the teacher.** Only the presenter changes the shared arm; "
                 "E-STOP works for everyone.")
#: the role line of the presenter's page
PRESENTER_TEXT = "**You present.** Your changes move the shared arm."
#: the role line of a page showing its own arm
MY_ARM_TEXT = ("**My arm.** Your own simulated arm: nothing you do here reaches the "
               "teacher's arm or anyone else's.")
FOLLOW, MY_ARM = "Follow the teacher", "My arm"
#: the browser's localStorage key holding its seat (a reload finds its arm again)
SEAT_KEY = "armlab_seat"
#: s a page has to say which seat it has (a loaded classroom laptop or a phone can take
#: tens of seconds to run a reloaded page), and s between questions
SEAT_WAIT_S = 180.0
SEAT_ASK_S = 4.0
#: Hz of the ghost's pose; the overview tables refresh every :data:`TABLE_EVERY` ticks
GHOST_HZ = 10.0
TABLE_EVERY = 10
#: scene node of a student's ghost on a presenter's page (its own scene), and of its label
GHOST_ROOT = "/class/ghost"
GHOST_LABEL = f"{GHOST_ROOT}/label"
#: m the ghost's label stands above the top of the ghost
GHOST_LABEL_ABOVE = 0.06


def ghost_text(name: str) -> str:
    """What the label over a student's ghost says."""
    return f"{name}'s arm"


@dataclass
class _GhostView:
    """A student's ghost on one presenter's page."""

    arm: ArmView
    label: viser.LabelHandle
    text: str


@dataclass
class _Ghost:
    """The student's arm the presenters' pages show as a ghost."""

    student: int  #: their page
    loop: Any  #: their arm's loop
    views: dict[int, _GhostView] = dataclasses.field(default_factory=dict)  #: by presenter


@dataclass
class _PageState:
    client: viser.ClientHandle
    role: viser.GuiMarkdownHandle
    code: viser.GuiTextHandle
    view: viser.GuiDropdownHandle
    screen: UpdateScreen
    seat: str | None = None
    private: LessonHandle | None = None  #: the page's own lesson, while it shows "My arm"
    figures: Figures | None = None  #: of its own lesson when it closed
    tags: dict[str, str | None] | None = None  #: and which challenge's run measured each
    results: list = dataclasses.field(default_factory=list)  #: and its challenge runs
    overview: ClassOverview | None = None  #: a presenter's class overview
    mine: MyChallenge | None = None  #: a student's own challenge panel


class ClassLab(Protocol):
    """What a room uses of the lab it is part of (:class:`armlab.app.lab.server.Lab`)."""

    @property
    def server(self) -> viser.ViserServer:
        """The lab's server (every page)."""
        ...

    @property
    def gate(self) -> Gate:
        """The lab's gate (its presenter cookie)."""
        ...

    @property
    def url(self) -> str:
        """The page's url with its token (what students scan)."""
        ...

    @property
    def host(self) -> str:
        """The interface the lab listens on (loopback: no other machine can join)."""
        ...

    @property
    def lesson(self) -> LessonHandle | None:
        """The shared lesson (None while switching)."""
        ...

    @property
    def open_lesson(self) -> Lesson:
        """The shared lesson open now (a private copy is built from it)."""
        ...

    @property
    def lesson_name(self) -> str:
        """The shared lesson's name (a challenge names the lesson it runs in)."""
        ...

    @property
    def lesson_ctx(self) -> LessonContext:
        """What the shared lesson was built for."""
        ...


class Room:
    """The classroom side of a :class:`armlab.app.lab.server.Lab` (see the module docstring).

    Args:
        lab: the lab (its server, shared lesson and url).
        realtime: the private arms run against the wall clock (False: as fast as possible).
        sandboxes: the private arms (default: a new :class:`Sandboxes`, started now: its
            worker process is ready by the first "My arm").

    Attributes:
        roles: presenters and followers.
    """

    def __init__(self, lab: ClassLab, *, realtime: bool = True,
                 sandboxes: Sandboxes | None = None) -> None:
        self.lab = lab
        self.roles = Roles(lab.server, new_passcode())
        self._sandboxes = Sandboxes(realtime=realtime) if sandboxes is None else sandboxes
        self._pages: dict[int, _PageState] = {}
        self._lock = threading.RLock()
        self._ghost: _Ghost | None = None  #: the student's arm shown as a ghost, or None
        #: the lab's challenge (set by :meth:`use_challenges`), each seat's runs, and the
        #: name each seat last had (the gradebook keeps a student who has left)
        self.desk: ChallengeDesk | None = None
        self._runs: dict[str, RunLog] = {}
        self._seat_names: dict[str, str] = {}
        #: each seat's number (1, 2, ... in the order seats first ran): the gradebook's seat
        #: column, which tells two students of one name apart without showing their key
        self._seat_numbers: dict[str, int] = {}
        self._stop = threading.Event()
        #: makes the private pages' frames, one after another (armlab.app.page.publisher)
        self._frames = FrameThread(name="armlab-private-frames")
        #: the shared lesson's updates, held back from pages that show their own arm
        self.stream = SharedStream(lab.server)
        lab.server.on_client_connect(self._welcome)
        lab.server.on_client_disconnect(self._goodbye)
        self._ticker = threading.Thread(target=self._tick_often, name="armlab-room",
                                        daemon=True)
        self._ticker.start()

    @property
    def sandboxes(self) -> Sandboxes:
        """The class's private arms."""
        return self._sandboxes

    def private_lessons(self) -> dict[int, LessonHandle]:
        """Client id -> the lesson that page shows as "My arm" (pages showing one only)."""
        with self._lock:
            return {cid: s.private for cid, s in self._pages.items() if s.private is not None}

    def pages(self) -> dict[int, str]:
        """Client id -> what that page shows and whether it holds a seat (for a person
        reading a log or a failed test)."""
        with self._lock:
            return {cid: f"{'presenter' if self.roles.is_presenter(cid) else s.view.value}"
                         f"{', seat' if s.seat else ''}{', own lesson' if s.private else ''}"
                    for cid, s in self._pages.items()}

    def private_lesson(self, client_id: int) -> LessonHandle | None:
        """The lesson page ``client_id`` shows as "My arm", or None."""
        with self._lock:
            state = self._pages.get(client_id)
            return None if state is None else state.private

    # -- pages joining and leaving -------------------------------------------------

    def _welcome(self, client: viser.ClientHandle) -> None:
        gui = client.gui
        screen = UpdateScreen(self.lab.server, gui=gui)  # the page's own controls
        # One atomic block: the page gets its fields only with their callbacks in place
        # (a page quick to choose My arm would otherwise change the View unheard).
        with client.atomic():
            role = gui.add_markdown(FOLLOWER_TEXT, order=-97.0)
            view = gui.add_dropdown("View", (FOLLOW, MY_ARM), initial_value=FOLLOW,
                                    order=-96.5, hint="Follow the teacher's arm, or try your "
                                                      "own gains on your own simulated arm")
            code = gui.add_text("Passcode", "", order=-96.0,
                                hint="The teacher types the passcode armlab serve printed")
            name = gui.add_text("Your name", "", order=-95.0,
                                hint="Shown to the teacher (e.g. when you press E-STOP)")
            state = _PageState(client, role, code, view, screen)
            state.mine = MyChallenge(client, on_run=lambda: self._run_mine(state))
            with self._lock:
                self._pages[client.client_id] = state
            name.on_update(lambda _e: self.roles.set_name(client.client_id, name.value))  # type: ignore[type-var]  # the callback's result is dropped by viser
            code.on_update(lambda _e: self._on_passcode(state))
            view.on_update(lambda _e: self._on_view(state))
            mask_text_input(client, code)  # typed as a password: dots on the projector
        self._presenter_link(state)
        threading.Thread(target=self._find_seat, args=(state,), daemon=True,
                         name="armlab-seat").start()

    def _goodbye(self, client: viser.ClientHandle) -> None:
        self.roles.forget(client.client_id)
        self.stream.forget(client.client_id)
        with self._lock:
            state = self._pages.pop(client.client_id, None)
        if state is not None:
            self._close_private(state, gone=True)
            if state.seat is not None:
                self._sandboxes.leave(state.seat, page=client.client_id)

    # -- the presenter -----------------------------------------------------------------

    def _on_passcode(self, state: _PageState) -> None:
        typed = state.code.value
        if len(typed.strip()) < len(self.roles.passcode):
            return  # still typing
        state.code.value = ""  # type: ignore[misc]  # viser: value's setter is apart from its getter, mypy sees none
        self._try_passcode(state, typed, refused="Passcode refused", then="", seconds=8.0)

    def _presenter_link(self, state: _PageState) -> None:
        """A page opened from the presenter link (``armlab serve`` prints it) presents at
        once; its passcode is checked, and counted, as a typed one."""
        code = presenter_link_code(self.lab.server, state.client.client_id,
                                   self.lab.gate.presenter_cookie)
        if code is not None:
            self._try_passcode(state, code, refused="Presenter link refused",
                               then=". Type the passcode into the Passcode field.",
                               seconds=12.0)

    def _try_passcode(self, state: _PageState, code: str, *, refused: str, then: str,
                      seconds: float) -> None:
        """The page presents if ``code`` is the passcode (checked and counted by
        :meth:`Roles.try_passcode`); else one notification ``refused`` saying why."""
        cid = state.client.client_id
        why = self.roles.try_passcode(cid, code, key=address_of(self.lab.server, cid))
        if why is None:
            self._present(state)
            return
        state.client.add_notification(refused, why + then, color="red",
                                      auto_close_seconds=seconds)

    def _present(self, state: _PageState) -> None:
        """Page ``state`` now presents: its Passcode and View fields go, the students' QR
        code and the class overview come."""
        if state.view.value != FOLLOW:
            state.view.value = FOLLOW  # type: ignore[misc]  # viser: value's setter is apart from its getter, mypy sees none; a presenter drives the shared arm
        state.code.remove()
        state.view.remove()
        if state.mine is not None:  # a presenter runs the challenge on the shared arm
            state.mine.remove()
        state.mine = MyChallenge(state.client, on_run=self._run_shared,
                                 whose="The shared arm's",
                                 button="Run the challenge on the shared arm")
        state.role.content = PRESENTER_TEXT
        gui = state.client.gui
        alone = loopback_warning(self.lab.host)
        with gui.add_folder("Students join", order=-94.0, expand_by_default=alone is not None):
            if alone is not None:  # the code below cannot be joined: said before it
                gui.add_html("<div role='alert'>"
                             f"{warning_html('Phones cannot join', alone, color='#a15c00')}</div>")
            # the url whole at every width: it wraps anywhere, never wider than the panel
            gui.add_html(f"<div style='text-align:center'>{qr_svg(self.lab.url)}"
                         "<div style='font-size:0.85em;overflow-wrap:anywhere;"
                         "word-break:break-all;max-width:100%;white-space:normal'>"
                         f"{esc(self.lab.url)}</div></div>")
        state.overview = ClassOverview(state.client, on_show=self.show_ghost,
                                       on_use=self.use_gains, on_gradebook=self.gradebook)
        state.client.add_notification("You present", "You now change the shared arm.",
                                      color="green", auto_close_seconds=5.0)

    def tell_presenters(self, title: str, body: str) -> None:
        """A red notification on every presenter's page."""
        clients = self.lab.server.get_clients()
        for cid in self.roles.presenters():
            if (client := clients.get(cid)) is not None:
                client.add_notification(title, body, color="red", auto_close_seconds=15.0)

    # -- "My arm" -------------------------------------------------------------------------

    def _find_seat(self, state: _PageState) -> None:
        """A reload: if the browser holds a seat that is still kept, show its arm again.

        Asked every :data:`SEAT_ASK_S` s until the page answers, leaves, or
        :data:`SEAT_WAIT_S` s have passed: a page that has only just connected may not
        answer the first question, and a busy one answers late."""
        try:
            key = ask_item(state.client, SEAT_KEY, every=SEAT_ASK_S, within=SEAT_WAIT_S)
        except (TimeoutError, RuntimeError):  # no answer, the page left, no localStorage
            return
        if key and self._sandboxes.has(key):
            state.seat = key
            state.view.value = MY_ARM  # type: ignore[misc]  # viser: value's setter is apart from its getter, mypy sees none; fires _on_view

    def _seat_of(self, state: _PageState) -> str:
        if state.seat is None:
            state.seat = secrets.token_urlsafe(16)
            state.client.local_storage.set_item(SEAT_KEY, state.seat)
        return state.seat

    def _on_view(self, state: _PageState) -> None:
        with self._lock:
            if state.view.value == FOLLOW:
                self._close_private(state)
                return
            if state.private is not None:
                return
            lab = self.lab
            lesson = lab.open_lesson
            if not lesson.private:
                notify(state.client, "No private arm here",
                       f"The lesson {lesson.title!r} has no private arm yet; you follow "
                       "the teacher.")
                state.view.value = FOLLOW  # type: ignore[misc]  # viser: value's setter is apart from its getter, mypy sees none
                return
            try:
                seat = self.sandboxes.seat(self._seat_of(state), page=state.client.client_id)
            except ClassFull as exc:
                notify(state.client, "The class is full", str(exc))
                state.view.value = FOLLOW  # type: ignore[misc]  # viser: value's setter is apart from its getter, mypy sees none
                return
            ctx = replace(lab.lesson_ctx, backend="sim", port=None, baud=None,
                          joint_map=None, arms=seat, frames=self._frames)
            self.show_shared(state.client, shown=False)
            self.stream.hold(state.client.client_id)
            try:
                state.private = lesson.build(Page(state.client), ctx)
                collector.keep()  # the page's lesson lives as long as the page
            except BaseException:
                self.stream.release(state.client)
                self.show_shared(state.client, shown=True)
                state.view.value = FOLLOW  # type: ignore[misc]  # viser: value's setter is apart from its getter, mypy sees none
                raise
            state.role.content = MY_ARM_TEXT

    def _close_private(self, state: _PageState, *, gone: bool = False) -> None:
        """Close the page's own lesson (its arm is kept); unless the page is ``gone``,
        show the shared lesson there again."""
        with self._lock:
            lesson, state.private = state.private, None
        if lesson is None:
            return
        state.figures, state.tags = lesson.run_figures(), tags_of(lesson)
        state.results = results_of(lesson)
        lesson.close()
        collector.closed()
        if not gone:
            self.stream.release(state.client)  # the shared lesson as it is now, then live
            self.show_shared(state.client, shown=True)
            state.role.content = FOLLOWER_TEXT

    def lesson_changed(self) -> None:
        """The shared lesson was replaced: pages showing their own arm follow again."""
        with self._lock:
            states = [s for s in self._pages.values() if s.private is not None]
        for state in states:
            self._close_private(state)
            state.view.value = FOLLOW  # type: ignore[misc]  # viser: value's setter is apart from its getter, mypy sees none
            notify(state.client, "The teacher opened another lesson",
                   "You follow the teacher again; choose My arm to try it yourself.")

    def show_shared(self, client: viser.ClientHandle, *, shown: bool) -> None:
        """Show or hide the shared lesson's panel on ``client``'s page only."""
        lesson = self.lab.lesson
        handles = () if lesson is None else lesson.gui_handles()
        for handle in handles:
            queue(client, GuiUpdateMessage(uuid_of(handle),
                                           {"visible": bool(handle.visible) and shown}))

    # -- the class overview ------------------------------------------------------------

    def rows(self) -> list[StudentRow]:
        """Every student (a page that does not present), as the overview shows them."""
        with self._lock:
            states = [s for s in self._pages.values()
                      if not self.roles.is_presenter(s.client.client_id)]
        rows = []
        for s in states:
            cid = s.client.client_id
            lesson = s.private
            gains = None if lesson is None else lesson.gain_controls()
            params = None
            if gains is not None:
                params = gains.params
            elif s.seat is not None:
                params = self._sandboxes.kept_params(s.seat)
            figures = lesson.run_figures() if lesson is not None else (s.figures or {})
            rows.append(StudentRow(cid, self.roles.name(cid), str(s.view.value), params,
                                   figures, best=self.best_of(cid)))
        return sorted(rows, key=lambda r: r.client_id)

    def _loop_of(self, client_id: int) -> Any:
        with self._lock:
            state = self._pages.get(client_id)
        if state is None or state.seat is None:
            return None
        return self._sandboxes.loop_of(state.seat)

    def show_ghost(self, client_id: int | None) -> None:
        """Draw the arm of student ``client_id`` as a ghost beside the shared one, labelled
        with their name, on every presenter's page and no other (each page's own scene),
        and frame each presenter's view to take it in with the shared arm (None: take it
        away, and frame the shared arm alone again)."""
        with self._lock:
            old, self._ghost = self._ghost, None
            if old is not None:
                for view in old.views.values():
                    remove_quietly(view.arm.root)
            loop = None if client_id is None else self._loop_of(client_id)
            if client_id is not None and loop is None:
                self.tell_presenters("Nothing to show", "That student has no arm of their own "
                                     "yet (they choose My arm).")
            if client_id is not None and loop is not None:
                self._ghost = _Ghost(client_id, loop)
            shown = self._sync_ghost()
        clients = self.lab.server.get_clients()
        for cid in set(shown) | (set() if old is None else set(old.views)):
            if (client := clients.get(cid)) is not None:
                camera.also_frame(client, shown.get(cid, ()))
                camera.reframe(client)
        self._ghost_shown()

    def _sync_ghost(self) -> dict[int, tuple[str, ...]]:
        """Draw the ghost on the presenters' pages that do not show it yet (a page that
        presents since) and forget the pages gone; presenter -> the ghost's roots, for the
        pages it was drawn on now (the lock held)."""
        ghost = self._ghost
        if ghost is None:
            return {}
        clients = self.lab.server.get_clients()
        presenters = {cid: clients[cid] for cid in self.roles.presenters() if cid in clients}
        for cid in set(ghost.views) - set(presenters):
            remove_quietly(ghost.views.pop(cid).arm.root)
        drawn: dict[int, tuple[str, ...]] = {}
        for cid, client in presenters.items():
            if cid not in ghost.views:
                view = ghost.views[cid] = self._draw_ghost(client, ghost)
                drawn[cid] = (view.arm.moving_root, view.label.name)
        return drawn

    def _draw_ghost(self, client: viser.ClientHandle, ghost: _Ghost) -> _GhostView:
        """The student's ghost on one presenter's page, posed as their arm is now, and its
        label just above it."""
        arm = ArmView(Page(client), ghost.loop.model, root=GHOST_ROOT, color=GHOST_RGBA)
        arm.see_through("torso", opacity=0.0)  # the student's arm, not a body it stands on
        arm.root.position = GHOST_OFFSET
        snap = ghost.loop.recorder.snapshot(0.1)
        if len(snap["t"]):
            arm.set_q(snap["q"][-1])
        pts = camera.framed_points(client.scene, (arm.moving_root,))
        if len(pts) == 0:  # nothing drawn that moves: above its root
            pts = np.asarray([GHOST_OFFSET], dtype=float)
        above = (0.5 * (pts[:, 0].min() + pts[:, 0].max()),
                 0.5 * (pts[:, 1].min() + pts[:, 1].max()),
                 pts[:, 2].max() + GHOST_LABEL_ABOVE)
        text = ghost_text(self.roles.name(ghost.student))
        label = theme.add_label(client.scene, GHOST_LABEL, text, anchor="bottom-center",
                                position=tuple(np.subtract(above, GHOST_OFFSET)))
        return _GhostView(arm, label, text)

    def _ghost_shown(self) -> None:
        """Tell every presenter's overview whose ghost shows (its button hides it then)."""
        with self._lock:
            student = None if self._ghost is None else self._ghost.student
            overviews = [s.overview for s in self._pages.values() if s.overview is not None]
        for overview in overviews:
            overview.showing(student)

    def use_gains(self, client_id: int) -> str:
        """Copy student ``client_id``'s gains to the shared arm; what happened, for a person."""
        loop = self._loop_of(client_id)
        lesson = self.lab.lesson
        gains = None if lesson is None else lesson.gain_controls()
        if loop is None:
            return "That student has no arm of their own yet: no gains to copy."
        if gains is None:
            return "The open lesson has no gains to set."
        params = loop.params
        try:
            gains.set_params(params)
        except ValueError as exc:
            return f"Not copied: {exc}"
        return (f"The shared arm now has {self.roles.name(client_id)}'s gains: Kp {params.kp:g}, "
                f"Kv {params.kv:g}, M_env {params.m_env:g}, D_env {params.d_env:g}, "
                f"K_env {params.k_env:g}, K_f {params.k_f:g}.")

    def _tick_often(self) -> None:
        k = 0
        while not self._stop.wait(1.0 / GHOST_HZ):
            k += 1
            if k % TABLE_EVERY == 0:
                collector.tidy(every_s=collector.TIDY_EVERY_S)  # what closed lessons left
            try:
                self._tick(tables=k % TABLE_EVERY == 0)
            except Exception as exc:  # a page gone mid-update: next tick
                print(f"armlab: class overview: {type(exc).__name__}: {exc}"[:200],
                      file=sys.stderr, flush=True)

    # -- challenges --------------------------------------------------------------------

    def use_challenges(self, desk: ChallengeDesk) -> None:
        """Judge every student's runs against ``desk``'s challenge (the lab's)."""
        self.desk = desk

    def _run_shared(self) -> str:
        """Start the challenge's run on the shared arm (a presenter's page asked)."""
        if self.desk is None:
            raise ValueError("the teacher has set no challenge")
        return self.desk.run()

    def _run_mine(self, state: _PageState) -> str:
        """Start the challenge's run on the student's own arm (their page asked); what was
        started. ValueError (shown to them) when there is nothing to run it on."""
        desk = self.desk
        challenge = None if desk is None else desk.challenge
        if challenge is None:
            raise ValueError("the teacher has set no challenge")
        lesson = state.private
        if lesson is None:
            raise ValueError("choose My arm in View first: the challenge runs on your own arm")
        before = figures_of(lesson)
        started = start_run(lesson, self.lab.lesson_name, challenge)
        if tags_of(lesson) is None and state.seat is not None:  # the log tags its run
            with self._lock:
                self._seat_log(state.seat).expect(challenge, before)
        return started

    def _observe(self) -> None:
        """Read each student's figures (measured here, from their own arm) into their
        seat's runs, and show each page where its runs stand (a presenter's page: the
        shared arm's)."""
        with self._lock:
            states = list(self._pages.values())
        desk = self.desk
        challenge = None if desk is None else desk.challenge
        for s in states:
            if self.roles.is_presenter(s.client.client_id):
                if s.mine is not None and desk is not None:
                    s.mine.show(challenge, desk.runs())  # the shared arm's runs
                continue
            log = None
            if s.seat is not None:
                figures = figures_of(s.private) if s.private is not None else (
                    _plain(dict(s.figures)) if s.figures is not None else {})
                tags = tags_of(s.private) if s.private is not None else s.tags
                results = results_of(s.private) if s.private is not None else s.results
                with self._lock:
                    log = self._seat_log(s.seat)
                    self._seat_names[s.seat] = self.roles.name(s.client.client_id)
                    log.take(results)
                    if figures:
                        log.observe(figures, tags=tags)
            if s.mine is not None:
                with self._lock:  # (the gradebook may observe from another thread)
                    s.mine.show(challenge, log)

    def _seat_log(self, seat: str) -> RunLog:
        """Seat ``seat``'s runs (a new log, and the seat's number, the first time; the lock
        held)."""
        if seat not in self._runs:
            self._runs[seat] = RunLog()
            self._seat_numbers[seat] = len(self._seat_numbers) + 1
        return self._runs[seat]

    def gradebook(self) -> tuple[str, bytes]:
        """(file name, CSV) of the gradebook: one row per student (every seat, and every
        student page without one), their best run against the challenge."""
        challenge = None if self.desk is None else self.desk.challenge
        if challenge is None:
            raise ValueError("pick a challenge first (the Challenge folder)")
        self._observe()
        with self._lock:
            rows = [(self._seat_names.get(seat, "?"), str(self._seat_numbers[seat]),
                     log.best(challenge)) for seat, log in self._runs.items()]
            rows += [(self.roles.name(s.client.client_id), "", None)
                     for s in self._pages.values()
                     if s.seat is None and not self.roles.is_presenter(s.client.client_id)]
        stamp = utc_now().replace(":", "").replace("-", "")
        name = f"armlab-gradebook-{challenge.key}-{stamp}.csv"
        return name, gradebook_bytes(challenge, rows)

    def best_of(self, client_id: int) -> Any:
        """The best run of page ``client_id``'s seat against the challenge, judged, or
        None."""
        challenge = None if self.desk is None else self.desk.challenge
        with self._lock:
            state = self._pages.get(client_id)
            log = None if state is None or state.seat is None else self._runs.get(state.seat)
            return None if challenge is None or log is None else log.best(challenge)

    def _tick(self, *, tables: bool) -> None:
        if tables:
            self._observe()
        with self._lock:
            ghost = self._ghost
            overviews = [s.overview for s in self._pages.values() if s.overview is not None]
        if ghost is not None:
            if self._loop_of(ghost.student) is not ghost.loop:  # the student has left
                self.show_ghost(None)
            else:
                self._pose_ghost(ghost)
        if tables and overviews:
            rows = self.rows()
            challenge = None if self.desk is None else self.desk.challenge
            lesson = all_lessons().get(self.lab.lesson_name)
            columns = {} if lesson is None else lesson.overview_figures()
            for overview in overviews:
                overview.refresh(rows, challenge=challenge, columns=columns)

    def _pose_ghost(self, ghost: _Ghost) -> None:
        """Pose the ghost on each presenter's page as the student's arm is now, with their
        name as it is now; draw it on a page that presents since (framed there)."""
        with self._lock:
            if self._ghost is not ghost:
                return  # hidden or replaced meanwhile
            drawn = self._sync_ghost()
            views = list(ghost.views.values())
        snap = ghost.loop.recorder.snapshot(0.1)
        text = ghost_text(self.roles.name(ghost.student))
        for view in views:
            if len(snap["t"]):
                view.arm.set_q(snap["q"][-1])
            if view.text != text:
                view.label.text = view.text = text
        clients = self.lab.server.get_clients()
        for cid, roots in drawn.items():
            if (client := clients.get(cid)) is not None:
                camera.also_frame(client, roots)
                camera.reframe(client)
        if drawn:
            self._ghost_shown()

    def close(self) -> None:
        """Close every private lesson and the class's arms."""
        self._stop.set()
        with self._lock:
            ghost, self._ghost = self._ghost, None
        for view in () if ghost is None else list(ghost.views.values()):
            remove_quietly(view.arm.root)
        with self._lock:
            states = list(self._pages.values())
        for state in states:
            self._close_private(state)
        self._frames.close()
        self._sandboxes.close()


def _plain(figures: dict[str, Any]) -> dict[str, float | None]:
    """Figures as plain floats (None kept)."""
    return {k: None if v is None else float(v) for k, v in figures.items()}
