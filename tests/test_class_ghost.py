"""A student's ghost in a class (armlab/app/classroom/room.py, ``Room.show_ghost``): the
presenter's **Show** draws the student's arm, labelled with their name, on the presenters'
pages only, and frames it with the shared arm; Hide, or the student leaving, takes it away.

Headless pages (armlab/app/testing/wsclient.py) of a real classroom lab on a free loopback
port: every scene message a page is sent is recorded, so "no node of the ghost" on a page
is what that page was sent, not what a renderer chose to draw.
"""

from __future__ import annotations

import threading
from typing import Any

import numpy as np
import pytest
import viser
from _helpers import client_of, project, settled, wait_for

from armlab.app.classroom.room import GHOST_LABEL, GHOST_ROOT
from armlab.app.lab.server import Lab, ServeOptions
from armlab.app.page import camera
from armlab.app.testing.wsclient import HeadlessClient
from armlab.app.viser_ext.handles import scene_nodes


class Recorder:
    """The scene messages of one page that name a node under :data:`GHOST_ROOT`."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.messages: list[dict[str, Any]] = []

    def __call__(self, m: dict[str, Any], _t: float) -> None:
        name = m.get("name")
        if isinstance(name, str) and (name == GHOST_ROOT or name.startswith(GHOST_ROOT + "/")):
            with self.lock:
                self.messages.append(m)

    def kinds(self) -> list[str]:
        with self.lock:
            return [m["type"] for m in self.messages]

    def label_texts(self) -> list[str]:
        with self.lock:
            return [m["props"]["text"] for m in self.messages
                    if m["type"] == "LabelMessage" and m["name"] == GHOST_LABEL]

    def removed(self) -> bool:
        """The ghost's last message removes its root."""
        with self.lock:
            last = [m for m in self.messages if m["name"] == GHOST_ROOT]
            return bool(last) and last[-1]["type"] == "RemoveSceneNodeMessage"


def _page(lab: Lab) -> tuple[HeadlessClient, Recorder, int]:
    """A page of ``lab`` recording its ghost messages, and its client id."""
    before = set(lab.server.get_clients())
    seen = Recorder()
    page = HeadlessClient(lab.local_url.replace("http://", "ws://"), on_message=seen).connect()
    page.wait_for(lambda: page.shows("Passcode") and page.shows("Kp (1/s²)"), 60.0,
                  "the Passcode field and the Kp slider")
    page.wait_for(lambda: bool(set(lab.server.get_clients()) - before), 30.0, "the client")
    (cid,) = set(lab.server.get_clients()) - before
    return page, seen, cid


def test_a_pages_framing_takes_in_its_own_nodes_with_the_shared_view():
    """camera.also_frame: one page's framing of the shared lesson's view takes in nodes
    of that page's own scene too (a presenter's ghost); another page's does not."""
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        with client_of(server) as page, client_of(server):
            clients = server.get_clients()  # (ids in the order the pages joined)
            mine, theirs = clients[min(clients)], clients[max(clients)]
            server.scene.add_box("/shared/arm", dimensions=(0.2, 0.2, 0.4),
                                 position=(0.0, 0.0, 0.2))
            camera.show(server, camera.View(roots=("/shared",), direction=(-1.0, 0.2, -0.3)))
            mine.scene.add_box("/class/ghost/arm", dimensions=(0.2, 0.2, 0.4),
                               position=(0.0, 1.5, 0.2))
            mine.scene.add_label("/class/ghost/label", "Ayu's arm", position=(0.0, 1.5, 0.5))
            camera.also_frame(mine, ("/class/ghost/arm", "/class/ghost/label"))
            assert camera.also_framed(mine) and not camera.also_framed(theirs)
            _, shared = camera.page_framing(theirs)
            _, framed = camera.page_framing(mine)
            assert len(framed) == len(shared) + 9 + 1  # the box's origin and corners, the label
            assert framed[:, 1].max() == pytest.approx(1.6)  # the far side of the ghost
            assert shared[:, 1].max() == pytest.approx(0.1)
            # Frame: the camera sent to the page shows both within the view
            page.wait_for(lambda: mine.camera._state.update_timestamp != 0.0,
                          what="the page's camera report")
            assert camera.reframe(mine)
            last = camera.last_framing[mine]
            assert len(last.points) == len(framed)
            x, y, depth = project(framed, last.position, last.look_at, (0.0, 0.0, 1.0),
                                  last.fov, last.aspect)
            assert np.all(depth > 0) and max(np.abs(x).max(), np.abs(y).max()) <= 1.0
            # a ghost taken away: the shared view alone again
            camera.also_frame(mine, ())
            assert len(camera.page_framing(mine)[1]) == len(shared)
    finally:
        server.stop()


@pytest.mark.slow
def test_show_draws_the_students_ghost_named_on_the_presenters_page_only_and_frames_it():
    with Lab(ServeOptions(http_port=0, classroom=True)) as lab:
        teacher, t_seen, t_id = _page(lab)
        ayu, a_seen, a_id = _page(lab)
        bo, b_seen, b_id = _page(lab)
        with teacher, ayu, bo:
            teacher.set_value("Passcode", lab.roles.passcode)
            teacher.wait_for(lambda: teacher.shows("Show"), 60.0, "the class overview")
            ayu.set_value("Your name", "Ayu")
            wait_for(lambda: lab.roles.name(a_id) == "Ayu", 30.0, "Ayu's name")
            for page in (ayu, bo):  # both students on their own arm (their own scene)
                page.set_value("View", "My arm")
            wait_for(lambda: {a_id, b_id} <= set(lab.room.private_lessons()), 120.0,
                     "both students' own lessons")
            option = f"Ayu (#{a_id})"
            teacher.wait_for(lambda: option in teacher.find("Student").props["options"], 60.0,
                             "Ayu in the Student picker")
            teacher.set_value("Student", option)
            teacher.click("Show")

            # the ghost and its label, named, on the presenter's page
            teacher.wait_for(lambda: t_seen.label_texts() == ["Ayu's arm"], 60.0,
                             lambda: f"the ghost's label; sent {t_seen.label_texts()}")
            assert "GlbMessage" in t_seen.kinds() or "MeshMessage" in t_seen.kinds()
            teacher.wait_for(lambda: teacher.shows("Hide"), 30.0, "the button to say Hide")
            # everything the server had sent every page, and each student's own page, by
            # now has reached the students too: none of it names the ghost
            for page, cid in ((ayu, a_id), (bo, b_id)):
                settled(lab.server, page)
                settled(lab.server.get_clients()[cid], page)
            assert a_seen.kinds() == [] and b_seen.kinds() == [], \
                "a student's page was sent the ghost"
            assert not any(n.startswith(GHOST_ROOT) for n in scene_nodes(lab.server.scene))

            # the presenter's framing takes the ghost in with the shared arm
            client = lab.server.get_clients()[t_id]
            roots = camera.also_framed(client)  # the ghost's arm and its label
            assert GHOST_LABEL in roots and all(r.startswith(GHOST_ROOT + "/") for r in roots)
            ghost_pts = camera.framed_points(client.scene, roots)
            view, arm_pts = camera._framed_scene(lab.server.scene)  # the shared lesson's
            assert len(ghost_pts) > 8
            _, framed = camera.page_framing(client)  # the arm's points, then the ghost's
            assert len(framed) == len(arm_pts) + len(ghost_pts)
            label = camera.node_points(client.scene, (GHOST_LABEL,))
            assert len(label) == 1 and label[0, 2] >= ghost_pts[:, 2].max() - 1e-9  # above

            def sent_framed() -> bool:
                """The camera last sent to the teacher shows the arm, the ghost and its
                label within the view."""
                last = camera.last_framing.get(client)
                if last is None or len(last.points) != len(framed) or not teacher.camera:
                    return False
                x, y, depth = project(np.vstack([framed, label]), teacher.camera["position"],
                                      teacher.camera["look_at"], view.up, last.fov,
                                      last.aspect)
                return bool(np.all(depth > 0) and np.all(np.abs(x) <= 1.0)
                            and np.all(np.abs(y) <= 1.0))

            teacher.wait_for(sent_framed, 60.0, lambda: "the teacher's camera on the arm and "
                             f"the ghost; framed {camera.last_framing.get(client)}, sent "
                             f"{teacher.camera}")
            # Frame takes it in too
            assert camera.reframe(client)
            assert len(camera.last_framing[client].points) == len(framed)

            # Hide (the button pressed again) takes it away, and the framing with it
            teacher.click("Hide")
            teacher.wait_for(t_seen.removed, 30.0, "the ghost removed")
            teacher.wait_for(lambda: teacher.shows("Show"), 30.0, "the button to say Show")
            assert len(camera.page_framing(client)[1]) == len(arm_pts)

            # shown again, then Ayu leaves: it goes with her
            n = len(t_seen.label_texts())
            teacher.click("Show")
            teacher.wait_for(lambda: len(t_seen.label_texts()) == n + 1, 60.0, "shown again")
            ayu.close()
            teacher.wait_for(t_seen.removed, 60.0, "the ghost gone with its student")
            wait_for(lambda: len(camera.page_framing(client)[1]) == len(arm_pts), 30.0,
                     "the framing of the shared arm alone")
            assert b_seen.kinds() == []
