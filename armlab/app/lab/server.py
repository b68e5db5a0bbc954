"""The lab's web server: one viser server, an always-visible E-STOP and a lesson switcher.

``Lab`` owns the :class:`LabServer` (a ``viser.ViserServer`` that refuses the
public share tunnel) and the lesson currently shown. Lessons live in
``armlab.app.lessons``; the lab builds the one chosen for the robot and lets the page
switch between lessons. The E-STOP button belongs to the lab, not to a lesson,
so it stays at the top of the control panel whatever lesson is open.

Security: the server binds to loopback unless told otherwise (a robot must not
be commandable from the whole network by default), never opens the share
tunnel (it needs the internet and would expose the robot), and its websocket is
behind :mod:`armlab.app.classroom.gate`: only the lab's own page, opened from the URL with the
token, gets the robot's state and controls.
"""

from __future__ import annotations

import contextlib
import io
import logging
import socket
import sys
import threading
import time
import urllib.error
import urllib.request
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import viser

from armlab.app.classroom.gate import PRESENTER_QUERY, Gate, check_token, gated, new_token
from armlab.app.classroom.roles import Roles
from armlab.app.classroom.room import Room
from armlab.app.lessons import Lesson, LessonContext, LessonHandle
from armlab.app.lessons.catalog import all_lessons, default_lesson
from armlab.app.lessons.challenge_panel import ChallengeDesk
from armlab.app.page.camera import reframe, reframe_on_reshape
from armlab.app.page.inputs import UpdateScreen
from armlab.app.page.labels import install as install_labels
from armlab.app.page.look import Looks
from armlab.app.page.number_keys import install as install_number_keys
from armlab.app.page.panels import install as install_panels
from armlab.app.page.stop_first import install as install_stop_first
from armlab.app.page.theme import PageStyle
from armlab.app.viser_ext import require_hooks
from armlab.app.viser_ext.fixes import install as install_viser_fixes
from armlab.app.workers.worker_process import ArmProcess
from armlab.control import collector

if TYPE_CHECKING:
    from armlab.app.arm.student_law import StudentLaw

#: Label at the top of the control panel.
PANEL_LABEL = "armlab"
#: px of the docked controls: viser's "large" width (24 em of 16 px). Every lesson's
#: name fits its picker at projector size (22 px) in it, with room to spare.
CONTROLS_PX = 384.0
#: s: how long a Python thread may hold the GIL while another waits for it. The
#: default 5 ms would let the web server's message encoding delay a control period
#: by up to 5 ms; 0.5 ms keeps the loop's wake-up late by well under a millisecond.
GIL_SWITCH_INTERVAL = 0.0005
#: s: the same in a classroom on real servos, where the shared loop shares the server
#: with the pages' frame threads: the web server's event loop and the loop get the GIL
#: back sooner (room of 30 pages, quiet machine, the class's clock then in the
#: server too: 20 pose frames/s a page at 0.25 ms against 15 at 0.5 ms).
CLASSROOM_SWITCH_INTERVAL = 0.00025
#: s: in a simulated classroom, where no arm's loop runs in the server
#: (armlab.app.workers.worker_process),
#: fewer forced switches between the frame threads and the event loop leave more of the
#: GIL to the pages' frames (room of 30, alternating: 18–20 pose frames/s a page at
#: 0.25 ms, 21–22 at 2 ms and 5 ms); 2 ms keeps a lesson's loop that runs here (hand,
#: quadruped) on time.
CLASSROOM_SIM_SWITCH_INTERVAL = 0.002


class LabServer(viser.ViserServer):
    """A ``viser.ViserServer`` whose share-URL tunnel can never be opened.

    The Share button is hidden with ``configure_theme(show_share_button=False)``;
    a client that still sends a share request (an old page, a hand-made
    message) is refused here, server-side.
    """

    def request_share_url(self, verbose: bool = True) -> str | None:
        """Refuse: the lab never opens a public tunnel. Returns None."""
        for client in self.get_clients().values():
            client.add_notification(
                "Sharing is off",
                "armlab never opens a public share link: it would expose the robot.",
                auto_close_seconds=5.0,
                color="yellow",
            )
        return None


@dataclass(frozen=True)
class ServeOptions:
    """What ``armlab serve`` was asked for.

    Attributes:
        robot: robot name (``kinematics.load_robot``).
        backend: "sim" (simulated arm and servos) or "serial" (Dynamixel bus).
        port: serial device for backend "serial", e.g. /dev/ttyUSB0.
        baud: serial baud rate (None: the backend's default, 1 Mbps).
        host: interface to listen on; loopback by default.
        http_port: first port to try; the next free one is used if it is taken.
        lesson: lesson name (None: the first lesson for the robot).
        realtime: run the control loop against the wall clock (False: as fast as
            possible, for tests).
        token: the access token the page's URL carries (None: a new random one).
        projector: large text on pages whose browser has not chosen (each page has its
            own "Projector" switch, kept in its browser: :mod:`armlab.app.page.theme`).
        classroom: roles (:mod:`armlab.app.classroom.roles`): only a page that typed the passcode
            changes the shared arm; every page may press E-STOP.
        tip_link, package_paths, joint_map: for a robot given as a URDF file (see
            :class:`armlab.app.lessons.LessonContext`).
        plain_on_software: a page whose browser draws WebGL on the CPU gets the plain
            look (:mod:`armlab.app.page.look`); False keeps the full look on every page.
        exercise: a student's law file (``--exercise``): the servo-arm lessons run it in
            place of the lab's own (:mod:`armlab.app.arm.student_law`); never in a classroom.
        next_to_robot: the person is next to the real arm (``--i-am-next-to-the-robot``):
            what a student's law on real servos needs.
    """

    robot: str = "receptionist_arm"
    backend: str = "sim"
    port: str | None = None
    baud: int | None = None
    host: str = "127.0.0.1"
    http_port: int = 8080
    lesson: str | None = None
    realtime: bool = True
    token: str | None = None
    projector: bool = False
    classroom: bool = False
    tip_link: str | None = None
    package_paths: tuple[str, ...] = ()
    joint_map: str | None = None
    plain_on_software: bool = True
    exercise: str | None = None
    next_to_robot: bool = False

    def __post_init__(self) -> None:
        if self.token is not None:
            check_token(self.token)
        if self.backend not in ("sim", "serial"):
            raise ValueError(f"backend: expected 'sim' or 'serial', got {self.backend!r}")
        if self.backend == "serial" and not self.port:
            raise ValueError("port: the serial backend needs --port DEV (e.g. /dev/ttyUSB0)")
        if not 0 <= self.http_port <= 65535:
            raise ValueError(f"http_port: expected 0..65535, got {self.http_port}")
        if self.exercise is not None and self.classroom:
            raise ValueError("--exercise runs a student's own code: only in their own lab, "
                             "never with --classroom")
        if self.exercise is not None and self.backend == "serial" and not self.next_to_robot:
            raise ValueError("--exercise with --backend serial drives the real arm with your "
                             "own law: add --i-am-next-to-the-robot (stay within reach of "
                             "the E-STOP and the servo power)")


#: host names that mean "every interface": the printed URL then names this machine's
#: address on the network, the one students type
WILDCARD_HOSTS = ("0.0.0.0", "::", "")


def lan_address() -> str:
    """This machine's address on its network (the interface of its default route).

    Connecting a UDP socket only picks the route; no packet is sent. "127.0.0.1" when
    the machine has no route.
    """
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        try:
            probe.connect(("192.0.2.1", 9))  # TEST-NET-1: never reached, only routed
            return str(probe.getsockname()[0])
        except OSError:
            return "127.0.0.1"


def _url_host(host: str) -> str:
    return f"[{host}]" if ":" in host else host


class Lab:
    """The running lab: server, E-STOP, lesson switcher and the open lesson.

    Args:
        options: what to serve.
        verbose: let viser print its connection log.

    Attributes:
        server: the :class:`LabServer`.
        token: the access token (:mod:`armlab.app.classroom.gate`).
        base_url: ``http://HOST:PORT`` (no token); HOST is this machine's network address
            when the lab listens on every interface.
        url: ``base_url/?token=TOKEN``: the page, with the token that opens it (what
            students type or scan).
        local_url: the same page through loopback (what this process itself loads).
        room: the classroom's pages, roles and private arms
        (:class:`armlab.app.classroom.room.Room`), with
            ``options.classroom`` only; None otherwise.
        lesson: handle of the open lesson (None while switching).
        lesson_ctx: what the open lesson was built for.
    """

    def __init__(self, options: ServeOptions, *, verbose: bool = False) -> None:
        # every hook into viser checked first: without the gate's, nothing is started
        require_hooks()  # raises HooksMissing (armlab.app.viser_ext)
        install_viser_fixes()  # before the server: GUI calls from callback threads
        self.options = options
        lessons = all_lessons()
        name = options.lesson or default_lesson(options.robot)
        if name not in lessons:
            raise ValueError(f"lesson: unknown {name!r}; known: {', '.join(sorted(lessons))}")
        self._lessons = lessons
        #: the student's own law (``--exercise``), watched for saves; None: the lab's own
        self.law: StudentLaw | None = None
        if options.exercise is not None:
            from armlab.app.arm.student_law import LIVE_LESSONS, StudentLaw

            if name not in LIVE_LESSONS:
                raise ValueError(f"--exercise: lesson {name} runs no law of yours; the "
                                 f"lessons {' and '.join(LIVE_LESSONS)} do")
            self.law = StudentLaw(options.exercise, servos=options.backend == "serial")
            self.law.start()
        if options.classroom and options.backend == "sim":  # the lab owns the process
            sys.setswitchinterval(CLASSROOM_SIM_SWITCH_INTERVAL)
        else:
            switch = CLASSROOM_SWITCH_INTERVAL if options.classroom else GIL_SWITCH_INTERVAL
            sys.setswitchinterval(min(sys.getswitchinterval(), switch))
        self._lock = threading.RLock()
        self._closed = False
        self.token = options.token or new_token()
        self.gate = Gate(self.token)
        # viser prints a banner on construction; the CLI prints its own url line.
        with contextlib.redirect_stdout(io.StringIO()), gated(self.gate) as placed:
            self.server = LabServer(host=options.host, port=options.http_port,
                                    label=PANEL_LABEL, verbose=verbose)
        try:
            placed.confirm()  # the server went through the gate, or it is stopped below
            self.screen = UpdateScreen(self.server)  # every client value checked first
            self.server.gui.configure_theme(show_share_button=False, control_width="large",
                                            brand_color=(30, 90, 170))
            # Docked, the controls never cover the 3D view: the camera frames the arm in
            # the space left between them and a lesson's charts docked on the left. A
            # docked panel keeps the width it had when it docked, which is the theme's
            # only if the theme reached the page first: its width is set, not left to that.
            self.server.gui.main_panel.dock_right()
            self.server.gui.main_panel.set_width(CONTROLS_PX)
            reframe_on_reshape(self.server)  # each page's camera fits its own 3D view
            install_stop_first(self.server)  # E-STOP: first Tab stop, Esc, pinned on a phone
            install_panels(self.server)  # a browser's collapsed side panels kept on reload
            install_number_keys(self.server)  # a number field says what it cannot take
            install_labels(self.server)  # every label tied to its field
            # a page drawing WebGL on the CPU gets the plain look (armlab.app.page.look)
            self.looks = Looks(self.server, plain_on_software=options.plain_on_software)
            port = self.server.get_port()
            wildcard = options.host in WILDCARD_HOSTS
            shown = lan_address() if wildcard else options.host
            local = ("::1" if options.host == "::" else "127.0.0.1") if wildcard else options.host
            self.base_url = f"http://{_url_host(shown)}:{port}"
            self.url = f"{self.base_url}/?token={self.token}"
            self.host = options.host  #: the interface it listens on
            self.local_url = f"http://{_url_host(local)}:{port}/?token={self.token}"
            self.room: Room | None = (Room(self, realtime=options.realtime)
                                      if options.classroom else None)
            #: the shared arm's own process in a simulated classroom: its loop's periods
            #: wait for no page (armlab.app.workers.worker_process)
            self.arm_process: ArmProcess | None = (
                ArmProcess(kind="own", realtime=options.realtime)
                if options.classroom and options.backend == "sim" else None)
            #: the teacher's link: a page opened from it presents at once (classroom only)
            self.presenter_url: str | None = None if self.room is None else \
                f"{self.url}&{PRESENTER_QUERY}={self.room.roles.passcode}"
            self._build_chrome(name)
            self.lesson: LessonHandle | None = None
            #: lesson name -> what it kept when last closed (LessonHandle.keep)
            self._kept: dict[str, object | None] = {}
            self._open(name)
            #: the challenge every page shows (armlab.app.lessons.challenge_panel)
            self.challenges = ChallengeDesk(self, shared=self.room is not None)
            if self.room is not None:
                self.room.use_challenges(self.challenges)
        except BaseException:
            if self.law is not None:
                self.law.close()
            if getattr(self, "room", None) is not None:
                self.room.close()  # type: ignore[union-attr]  # the getattr above: set, not None
            if getattr(self, "arm_process", None) is not None:
                self.arm_process.close()  # type: ignore[union-attr]  # the getattr above: set, not None
            with contextlib.redirect_stdout(io.StringIO()):
                self.server.stop()
            raise

    # -- chrome -----------------------------------------------------------------

    def _build_chrome(self, name: str) -> None:
        gui = self.server.gui
        self.estop_button = gui.add_button(
            "E-STOP", color="red", icon=viser.Icon.HAND_STOP,
            hint="Torque off on every servo now (key: Esc). Press Reset to go on.",
            order=-100.0)
        self.estop_button.on_click(lambda event: self.estop(by=event.client))
        self.frame_button = gui.add_button(
            "Frame", icon=viser.Icon.FOCUS_CENTERED, order=-95.0,
            hint="Point this page's camera at the lesson's robot again (after an orbit)")
        self.frame_button.on_click(lambda event: event.client is not None  # type: ignore[type-var]  # the callback's result is dropped by viser
                                   and reframe(event.client))
        if self.roles is not None:  # both only make things safe or change one page's view
            self.roles.open(self.estop_button, self.frame_button)
        ordered = sorted(self._lessons.values(), key=lambda lesson: lesson.sort_key)
        self._by_title = {lesson.title: lesson.name for lesson in ordered}
        self.lesson_dropdown = gui.add_dropdown(
            "Lesson", tuple(self._by_title), initial_value=self._lessons[name].title,
            order=-90.0, visible=len(ordered) > 1,
            hint="Switch to another lesson (stops the current one)")
        self.lesson_dropdown.on_update(self._on_lesson_picked)
        # each page its own Projector switch, kept in its browser (armlab.app.page.theme)
        self.page_style = PageStyle(self.server, projector=self.options.projector,
                                    order=-80.0)

    def _on_lesson_picked(self, event: viser.GuiEvent) -> None:
        name = self._by_title.get(str(self.lesson_dropdown.value))
        if name is None:
            return
        try:
            self.switch(name)
        except (ValueError, OSError, RuntimeError) as exc:
            if event.client is not None:
                event.client.add_notification("Cannot open lesson", str(exc), color="red",
                                              auto_close_seconds=8.0)

    # -- lessons ----------------------------------------------------------------

    def _context(self) -> LessonContext:
        o = self.options
        return LessonContext(robot=o.robot, backend=o.backend, port=o.port, baud=o.baud,
                             realtime=o.realtime, tip_link=o.tip_link,
                             package_paths=tuple(o.package_paths), joint_map=o.joint_map,
                             arm_process=self.arm_process, law=self.law, who=self._who)

    def _who(self, client_id: int) -> str:
        """The name page ``client_id`` goes by in the class ("" with no class)."""
        room = getattr(self, "room", None)
        return "" if room is None else room.roles.name(client_id)

    def _open(self, name: str) -> None:
        lesson = self._lessons[name]
        ctx = self._context()
        if lesson.robots and not lesson.works_with(ctx.robot):
            # the URDF options belong to the robot
            ctx = replace(ctx, robot=lesson.robots[0], tip_link=None, package_paths=(),
                          joint_map=None)
        ctx = replace(ctx, kept=self._kept.get(name))  # its last opening's, if any
        collector.tidy()  # what a closed lesson left, freed while no lesson runs here
        self.lesson = lesson.build(self.server, ctx)
        collector.keep()  # the lab and its lesson: out of the collector's full passes
        self.lesson_name = name
        self.lesson_ctx = ctx
        if self.room is not None:
            self.room.lesson_changed()
            # Save run, Export page, a CSV: any page may keep the run (the file goes to the
            # page that pressed; Open run stays the presenter's)
            self.room.roles.open(*self.lesson.page_only_buttons())

    def switch(self, name: str) -> None:
        """Close the open lesson and open lesson ``name``."""
        with self._lock:
            if self._closed or (self.lesson is not None and name == self.lesson_name):
                return
            previous = self.lesson_name
            if self.lesson is not None:
                try:  # its gains and measurements, for when it opens again
                    self._kept[previous] = self.lesson.keep()
                except Exception:  # (a lesson that cannot say loses them, never the switch)
                    logging.getLogger(__name__).exception(
                        "armlab: %s kept nothing for its next opening", previous)
                self.lesson.close()
                self.lesson = None
                collector.closed()
            try:
                self._open(name)  # its scene frames itself on every open page (page.camera)
            except (ValueError, OSError, RuntimeError):
                self._open(previous)  # back to the lesson that worked
                self.lesson_dropdown.value = self._lessons[previous].title  # type: ignore[misc]  # viser: value's setter is apart from its getter, mypy sees none
                raise
            # every page's switcher names the open lesson, however it was opened
            self.lesson_dropdown.value = self._lessons[name].title  # type: ignore[misc]  # viser: value's setter is apart from its getter, mypy sees none

    def estop(self, *, by: viser.ClientHandle | None = None) -> None:
        """Torque off now through the open lesson; never raises. In a classroom the
        presenters are told which page (``by``) pressed it."""
        lesson = self.lesson
        if lesson is not None:
            lesson.estop()
        if self.room is not None and by is not None:
            private = self.room.private_lesson(by.client_id)
            if private is not None:
                private.estop()  # the student's own arm too
            who = self.room.roles.name(by.client_id)
            self.room.tell_presenters("E-STOP", f"pressed by {who}; press Reset to go on.")

    @property
    def roles(self) -> Roles | None:
        """Presenters and followers (classroom only; None otherwise)."""
        return None if self.room is None else self.room.roles

    @property
    def open_lesson(self) -> Lesson:
        """The open lesson (a private copy is built from it)."""
        return self._lessons[self.lesson_name]

    # -- lifetime ---------------------------------------------------------------

    def wait_until_loadable(self, timeout: float = 10.0) -> None:
        """Block until the page answers an HTTP GET (raises OSError after ``timeout`` s)."""
        deadline = time.monotonic() + timeout
        while True:
            try:
                with urllib.request.urlopen(self.local_url, timeout=2.0) as reply:
                    if reply.status == 200:
                        return
            except (urllib.error.URLError, OSError) as exc:
                if time.monotonic() > deadline:
                    raise OSError(f"the page at {self.local_url} does not load: {exc}") from None
            time.sleep(0.05)

    def close(self) -> None:
        """Close the lesson (control loop stopped, hardware torque off) and stop the server."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            lesson, self.lesson = self.lesson, None
        try:
            self.challenges.close()
            if self.room is not None:
                self.room.close()
            if lesson is not None:
                lesson.close()
        finally:
            if self.law is not None:
                self.law.close()
            if self.arm_process is not None:
                self.arm_process.close()
            with contextlib.redirect_stdout(io.StringIO()):
                self.server.stop()
            collector.release()  # what the lab kept is garbage now: the collector's to free

    def __enter__(self) -> Lab:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
