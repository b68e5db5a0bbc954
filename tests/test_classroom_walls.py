"""A wall on a class's private arm (issue 54, the classroom's part): each student's arm
holds a wall of its own (the Contact tab's, the contact challenge's) in the class's
worker, whose force its loop records; no other arm meets it.

Headless first, the batched plant's walls against single plants' (the same force and
peak at every period, one arm's wall in no other arm's world); then a served class: a
student's private arm runs into its wall and the force is recorded while another's,
run along the same line at the same time, goes through where that wall is; the
contact challenge on a private arm scores the same figures twice, and
``armlab experiment contact``'s (the single plant's) within the batched plant's
difference from it.
"""

from __future__ import annotations

import numpy as np
import pytest
from _helpers import wait_for
from test_challenges import _present, _student
from test_contact_challenge import CONTACT, FIGURES, experiment

from armlab.app.lab.server import Lab, ServeOptions
from armlab.app.lessons.compliance_contact import BLOCK_SIZE_M, SHAPES
from armlab.control.params import DEFAULT
from armlab.hardware.families.dynamixel1.batched_backend import BatchedArmBackend, add_sim_arm
from armlab.hardware.families.dynamixel1.batched_plant import BatchedPlant
from armlab.hardware.families.dynamixel1.batched_walls import BatchedWalls
from armlab.hardware.families.dynamixel1.sim_backend import SimBackend
from armlab.hardware.servos.servo_spec import RX24F
from armlab.kinematics.catalog import load_robot

MODEL = load_robot("receptionist_arm")
Q0 = [np.array([0.0, 0.3, 0.3]), np.array([0.2, -0.4, 1.0]), np.array([-0.5, 0.8, -0.6]),
      np.array([1.0, 0.1, 0.2])]
GOALS = [np.array([0.5, 0.8, 1.0]), np.array([-0.3, 0.2, 0.4]), np.array([0.0, 0.3, 0.0]),
         np.array([1.2, -0.5, -1.0])]
PERIOD_STEPS = 16  #: a loop's period in plant steps (16 ms at 1 ms)


@pytest.mark.slow
def test_each_arms_wall_is_its_own_and_reads_as_a_single_plants():
    """Four arms moving to goals; arms 0 and 3 have a wall across their hand's way (the
    hand pushed into it), arm 1 a wall far off, arm 2 none; arm 0's wall is taken away
    and put back stiffer mid-run. Every period (16 steps) each arm's force and peak equal
    a single plant's with the same wall (``SimBackend``'s, to 1e-4 N: the states agree to
    1e-9), an impact's peak between periods is kept, and arm 2 reads nothing."""
    plant = BatchedPlant(MODEL, RX24F, dt=1e-3)
    walls = BatchedWalls(plant)
    backends = [BatchedArmBackend(plant, add_sim_arm(plant, q0=q0), lock=_NoLock(),
                                  walls=walls) for q0 in Q0]
    singles = [SimBackend(MODEL, q0=q0, dt=1e-3) for q0 in Q0]
    free = [SimBackend(MODEL, q0=q0, dt=1e-3) for q0 in Q0]
    for goal, *arms in zip(GOALS, backends, singles, free, strict=True):
        for be in arms:
            be.write(goal, np.full(3, 1.5))
    for _ in range(400):  # where each hand goes without a wall
        for be in free:
            be.plant.step()
    placed = {}
    for i, (q0, be) in enumerate(zip(Q0, free, strict=True)):
        if i == 2:
            continue
        a, b = MODEL.fk(q0)[:3, 3], MODEL.fk(be.plant.q)[:3, 3]
        normal = (a - b) / np.linalg.norm(a - b)
        origin = a + (0.33 if i != 1 else 3.0) * (b - a)  # (arm 1: far beyond its goal)
        placed[i] = (origin, normal, 5000.0 if i else 2e4, 30.0)
        for arm in (backends[i], singles[i]):
            arm.set_wall(origin, normal, stiffness=placed[i][2], damping=30.0)
    touched, kept_peak, worst = set(), False, 0.0
    for k in range(1, 801):
        walls.step()
        for be in singles:
            be.plant.step()
        if k == 320:  # arm 0's wall away, then back stiffer
            for arm in (backends[0], singles[0]):
                arm.set_wall(None, stiffness=1.0, damping=0.0)
        if k == 400:
            o, n, _, c = placed[0]
            for arm in (backends[0], singles[0]):
                arm.set_wall(o, n, stiffness=4e4, damping=c)
        if k % PERIOD_STEPS:
            continue
        for i, (be, ref) in enumerate(zip(backends, singles, strict=True)):
            if be.wall_setting() is None:
                assert ref.wall_setting() is None and be.wall_force() == 0.0, (k, i)
                continue
            force, peak = be.wall_force(), be.wall_peak()
            assert force == pytest.approx(ref.wall_force(), abs=1e-4), (k, i)
            assert peak == pytest.approx(ref.wall_peak(), abs=1e-4), (k, i)
            if force > 0.0:
                touched.add(i)
            kept_peak |= peak > force + 1.0  # an impact between two periods
        worst = max(worst, float(np.max(np.abs(
            plant.q - np.array([be.plant.q for be in singles])))))
    assert worst <= 1e-9
    assert touched == {0, 3} and kept_peak
    assert backends[2].wall_setting() is None and backends[1].wall_force() == 0.0
    setting = backends[3].wall_setting()
    assert setting is not None and np.allclose(setting.origin, placed[3][0])
    assert setting.stiffness == 5000.0
    # a wall is refused as the plant refuses it, and leaves the arm's wall as it was
    with pytest.raises(ValueError, match="normal"):
        backends[3].set_wall(np.zeros(3), np.zeros(3), stiffness=1e3, damping=0.0)
    with pytest.raises(ValueError, match="size"):  # a box of no width
        backends[3].set_wall(np.zeros(3), np.ones(3), stiffness=1e3, damping=0.0,
                             size=(0.0, 0.3, 0.02))
    assert backends[3].wall_setting() is setting
    # an arm that leaves takes its wall with it
    walls.forget(3)
    plant.remove_arm(3)
    walls.step()
    assert walls.setting(3) is None and backends[0].wall_setting() is not None


class _NoLock:
    """The test's one thread: a lock that does nothing."""

    def __enter__(self) -> None:
        return None

    def __exit__(self, *exc: object) -> None:
        return None


def _my_arm(lab: Lab, page, cid):  # noqa: ANN001, ANN202
    page.set_value("View", "My arm")
    wait_for(lambda: lab.room.private_lesson(cid) is not None, 90, "the student's own lesson")
    lesson = lab.room.private_lesson(cid)
    wait_for(lambda: lesson.rig.loop.status.t > 0.3, 60, "the private arm running")
    return lesson


@pytest.mark.slow
@pytest.mark.realtime
def test_a_private_arm_runs_into_its_own_wall_and_no_other_arm_meets_it():
    with Lab(ServeOptions(http_port=0, classroom=True)) as lab:
        teacher = _present(lab)
        ana, ana_id = _student(lab, "Ana")
        bo, bo_id = _student(lab, "Bo")
        with teacher, ana, bo:
            mine, theirs = _my_arm(lab, ana, ana_id), _my_arm(lab, bo, bo_id)
            # Ana ticks Wall on her page: the wall in her arm's world, in the worker
            ana.set_value(mine.contact.wall_on, True)
            wait_for(lambda: mine.rig.backend.wall_setting() is not None, 30, "Ana's wall")
            setting = mine.rig.backend.wall_setting()
            assert theirs.rig.backend.wall_setting() is None
            # both run the thesis line at once: hers into the wall, his through its place
            ana.click(mine.contact.button)
            theirs.run_line()
            wait_for(lambda: mine.contact.figures() is not None, 90,
                     lambda: f"Ana's run measured ({mine.contact.result.content!r})")
            wait_for(lambda: theirs.experiment is not None and theirs.experiment.done, 90,
                     "Bo's line")
            figures = mine.contact.figures()
            assert figures["fault"] is None
            assert figures["peak_force_n"] > 1.0 and figures["steady_force_n"] > 0.5
            snap = mine.rig.loop.recorder.snapshot()
            assert np.nanmax(snap["f_contact"]) > 0.5
            assert np.nanmax(snap["f_contact_peak"]) == pytest.approx(
                figures["peak_force_n"], rel=1e-12)
            # the server's view of her wall's force is the worker's record
            assert mine.rig.backend.wall_force() == pytest.approx(
                float(snap["f_contact"][-1]), abs=1e-12)
            # Bo's hand went through where her wall is; his record has no contact
            hand = lambda q: float((MODEL.fk(q)[:3, 3] - setting.origin) @ setting.normal)  # noqa: E731
            his = theirs.rig.loop.recorder.snapshot()
            assert np.all(np.isnan(his["f_contact"]))
            behind = 0.20 - float(mine.contact.distance.value) / 100.0  # the line's end, m
            assert behind > 0.01
            assert min(hand(q) for q in his["q"][-50:]) < -0.8 * behind  # through its place
            assert min(hand(q) for q in snap["q"][-50:]) > -0.25 * behind  # hers held at it
            assert theirs.rig.backend.wall_setting() is None
            # her page offers the block in the wall's place too, and her arm meets it
            assert mine.contact.shape.visible
            ana.set_value(mine.contact.shape, SHAPES[1])
            wait_for(lambda: (s := mine.rig.backend.wall_setting()) is not None
                     and s.size == BLOCK_SIZE_M, 30, "her wall a block")
            assert theirs.rig.backend.wall_setting() is None
            assert mine.rig.loop.status.fault is None and theirs.rig.loop.status.fault is None


@pytest.mark.slow
@pytest.mark.realtime
def test_the_contact_challenge_on_a_private_arm_scores_the_same_twice():
    with Lab(ServeOptions(http_port=0, classroom=True)) as lab:
        teacher = _present(lab)
        ana, ana_id = _student(lab, "Ana")
        with teacher, ana:
            mine = _my_arm(lab, ana, ana_id)
            lab.challenges.set_challenge(CONTACT)
            ana.wait_for(lambda: ana.shows("Run the challenge on my arm"), 30, "her button")
            runs = []
            for k in range(2):
                if k:  # something else in between: a step of her own
                    mine.run_step(joint=1, step_deg=10.0)
                    wait_for(lambda: mine.experiment.done, 60, "a step of her own")
                done = len(mine.challenge_results())
                ana.click("Run the challenge on my arm")
                wait_for(lambda d=done: len(mine.challenge_results()) > d, 120,
                         lambda: f"the contact challenge measured ({mine.last_run_text!r})")
                runs.append(mine.challenge_results()[-1][1])
            assert {f: runs[0][f] for f in FIGURES} == {f: runs[1][f] for f in FIGURES}
            assert mine.run_tags()["contact_peak_n"] == "contact"
            wait_for(lambda: lab.room.best_of(ana_id) is not None, 30, "judged on the server")
            # the single plant's experiment: the batched plant's arm may differ from it in
            # the last bits (numpy's tanh in its Coulomb friction); its figures are the
            # experiment's to 1e-9 (in practice every digit: 6.808688127683704 N peak,
            # 2.005627086863716 N steady at the lab's default gains), as the shared arm's
            ref = experiment(DEFAULT)
            for figure, key in FIGURES.items():
                assert runs[0][figure] is not None
                assert runs[0][figure] == pytest.approx(ref[key], rel=1e-9), figure
