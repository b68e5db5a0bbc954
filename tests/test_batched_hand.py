"""The class's hands: N batched hands and grasp controllers equal N single ones, and the
loop that runs them (armlab/app/workers/class_hands.py) gives each student's hand its
own grasp."""

from __future__ import annotations

import numpy as np
import pytest
from _helpers import wait_for

from armlab.app.workers.class_hands import ClassHands
from armlab.control.batched_grip import BatchedGrip
from armlab.control.experiments.hand_grip import GripOptions, run_grip
from armlab.control.grip import GripController, GripModel, GripParams
from armlab.control.grip_loop import MotorsOff, SetGripParams, SetObject
from armlab.hardware.sim.batched_hand import STATE, BatchedHand
from armlab.hardware.sim.hand_plant import GraspObject, HandParams, HandSim, make_hand

#: a class of five: objects of every kind (none, soft, hard, the slider's stiffest)
OBJECTS = (GraspObject(0.06, 1000.0, 1.0), None, GraspObject(0.04, 5000.0, 2.0),
           GraspObject(0.08, 200.0, 0.5), GraspObject(0.05, 20000.0, 5.0))
PARAMS = (GripParams(force_limit=0.8), GripParams(force_limit=1.0, approach_speed=0.08),
          GripParams(force_limit=0.3), GripParams(force_limit=1.3, approach_speed=0.01),
          GripParams(force_limit=0.5))


@pytest.mark.parametrize("lpf", [None, 200.0], ids=["unfiltered", "rc-filtered"])
@pytest.mark.slow
def test_batched_hands_and_controllers_equal_single_ones_through_whole_grasps(lpf):
    """Three simulated seconds: every hand closes, one object is taken away while held
    (the finger gives way and approaches again), limits go up and down, one hand opens
    and one has its motors switched off. Voltages, currents, forces, estimates and
    every finger's mode agree with N HandSim + GripController at every period."""
    hp = HandParams(current_lpf_hz=lpf)
    batch, singles = BatchedHand(hp), [HandSim(hp, obj) for obj in OBJECTS]
    model = GripModel.of(singles[0])
    grip, ctls = BatchedGrip(model), [GripController(model, p) for p in PARAMS]
    for obj, params in zip(OBJECTS, PARAMS, strict=True):
        batch.add(obj)
        grip.add(params)
    n = len(OBJECTS)
    cur_b = batch.step(np.zeros((n, 3)), 1e-3)
    cur_s = np.array([s.step(np.zeros(3), 1e-3) for s in singles])
    seen: set[str] = set()
    batched_side: list[tuple] = []
    single_side: list[tuple] = []

    def both(batched, single, k):  # noqa: ANN001, ANN202 - one command to both sides
        batched(k)
        single(ctls[k])

    for k in range(3000):
        if k == 10:
            for j in range(n):
                both(grip.close, GripController.close, j)
        if k == 1200:
            grip.set_params(2, GripParams(force_limit=0.9))
            ctls[2].set_params(GripParams(force_limit=0.9))
            batch.set_object(3, None)
            singles[3].set_object(None)
        if k == 1800:
            both(grip.open, GripController.open, 0)
            both(grip.stop, GripController.stop, 4)
        if k == 2400:
            grip.set_params(1, GripParams(force_limit=0.2))
            ctls[1].set_params(GripParams(force_limit=0.2))
        v_b = grip.update(cur_b)
        v_s = np.array([c.update(x) for c, x in zip(ctls, cur_s, strict=True)])
        cur_b = batch.step(v_b, 1e-3)
        cur_s = np.array([s.step(v, 1e-3) for s, v in zip(singles, v_s, strict=True)])
        batched_side.append((v_b, cur_b, batch.contact_force, grip.estimated_force()))
        single_side.append((v_s, cur_s, [s.contact_force for s in singles],
                            [c.estimated_force() for c in ctls]))
        for j, ctl in enumerate(ctls):
            assert grip.modes(j) == ctl.modes, (k, j)
            seen.update(ctl.modes)
    # every period's voltages, currents, forces and estimates, compared in one call
    # (axes: period, quantity, hand, finger)
    np.testing.assert_allclose(np.array(batched_side), np.array(single_side), rtol=0,
                               atol=1e-9)
    assert seen == {"idle", "opening", "closing", "squeezing", "holding", "empty"}
    assert batch.t == pytest.approx(singles[0].t)


def test_adding_and_removing_hands_leaves_the_others_as_they_were():
    batch = BatchedHand()
    a, b, c = (batch.add(GraspObject()) for _ in range(3))
    single = HandSim(obj=GraspObject())
    volts = np.array([[2.0, 1.0, 0.5]])
    for _ in range(50):
        batch.step(np.repeat(volts, batch.n_hands, axis=0), 1e-3)
        single.step(volts[0], 1e-3)
    batch.remove(a)
    d = batch.add(None)
    assert batch.ids == (b, c, d) and len({a, b, c, d}) == 4
    for _ in range(50):
        batch.step(np.repeat(volts, batch.n_hands, axis=0), 1e-3)
        single.step(volts[0], 1e-3)
    for name in STATE:
        np.testing.assert_allclose(batch.state(name)[batch.row(c)],
                                   getattr(single.state, name), rtol=0, atol=1e-12)
    fresh = HandSim()  # d joined at rest, around nothing
    for _ in range(50):
        fresh.step(volts[0], 1e-3)
    np.testing.assert_allclose(batch.finger_angle[batch.row(d)], fresh.finger_angle,
                               rtol=0, atol=1e-12)


def test_bad_input_to_the_batch_raises_and_changes_nothing():
    batch = BatchedHand()
    hand = batch.add(GraspObject())
    grip = BatchedGrip(GripModel.of(HandSim()))
    grip.add()
    before = {name: batch.state(name) for name in STATE}
    with pytest.raises(ValueError, match="finite"):
        batch.step(np.array([[1.0, np.nan, 1.0]]), 1e-3)
    with pytest.raises(ValueError, match=r"\(1, 3\)"):
        batch.step(np.ones((2, 3)), 1e-3)
    with pytest.raises(ValueError, match="does not fit"):
        batch.set_object(hand, GraspObject(size=0.5))
    with pytest.raises(ValueError, match="no member"):
        batch.remove(99)
    with pytest.raises(ValueError, match="finite"):
        grip.update(np.array([[np.inf, 0.0, 0.0]]))
    with pytest.raises(ValueError, match="force_limit must be <="):
        grip.add(GripParams(force_limit=5.0))
    for name in STATE:
        np.testing.assert_array_equal(batch.state(name), before[name])
    assert batch.t == 0.0 and grip.modes(0) == ("idle",) * 3


def wait_class(hands: ClassHands, seconds: float) -> None:
    """Let the class's loop run ``seconds`` more simulated seconds."""
    end = hands.plant.t + seconds
    wait_for(lambda: hands.plant.t >= end or hands.fault, 60, "the class's hands to run")
    assert not hands.fault, hands.fault


@pytest.mark.slow
def test_each_students_hand_grasps_with_its_own_force_and_matches_the_experiment():
    hands = ClassHands(realtime=False)
    try:
        obj = GraspObject(size=0.06, stiffness=1000.0)
        mine = hands.add(obj, GripParams(force_limit=0.4), history_s=6.0)
        theirs = hands.add(obj, GripParams(force_limit=0.8), history_s=6.0)
        wait_class(hands, 0.05)
        mine.post(SetGripParams(force_limit=0.4))
        mine.close_hand()
        wait_for(lambda: mine.status.closed_at is not None, 30, "the close")
        wait_class(hands, 2.1)
        # one student's grasp: the experiment's figures (the batch is the single hand)
        shown = mine.last_grasp(0.4)
        expected = run_grip(GripOptions(force=0.4, stiffness=1000.0, size=6.0, damping=1.0,
                                        lpf=None, duration=2.0), hand_plant=make_hand)
        for key in ("steady_force_N", "peak_force_N", "time_to_grasp_s"):
            assert shown[key] == pytest.approx(expected[key], rel=1e-6, abs=1e-9), key
        assert mine.status.modes == ("holding",) * 3
        # the other student's hand never moved
        assert theirs.status.modes == ("idle",) * 3 and theirs.status.closed_at is None
        assert np.all(theirs.snapshot(0.5)["force"] == 0.0)
        # the other closes on a harder object with a bigger F; mine keeps its 0.4 N
        theirs.post(SetObject(GraspObject(size=0.06, stiffness=5000.0)))
        theirs.close_hand()
        wait_for(lambda: theirs.status.closed_at is not None, 30, "their close")
        wait_class(hands, 2.0)
        np.testing.assert_allclose(theirs.snapshot(0.05)["force"][-1], 0.8, rtol=0.05)
        np.testing.assert_allclose(mine.snapshot(0.05)["force"][-1], 0.4, rtol=0.05)
        assert theirs.obj.stiffness == 5000.0 and mine.obj.stiffness == 1000.0
        assert mine.params.force_limit == 0.4 and theirs.params.force_limit == 0.8
        # E-STOP of one hand: its motors off, the springs open it; the other holds
        mine.post(MotorsOff())
        wait_class(hands, 0.5)
        assert mine.status.modes == ("idle",) * 3
        assert np.all(mine.snapshot(0.05)["force"][-1] == 0.0)
        assert theirs.status.modes == ("holding",) * 3
    finally:
        hands.close()


def test_a_freed_hand_says_so_and_the_class_goes_on():
    hands = ClassHands(realtime=False)
    try:
        gone = hands.add(None, GripParams(), history_s=2.0)
        kept = hands.add(GraspObject(), GripParams(), history_s=2.0)
        hands.free(gone)
        hands.free(gone)  # twice: nothing
        assert hands.n_hands == 1
        assert "freed" in gone.status.fault and not gone.status.running
        with pytest.raises(ValueError, match="freed"):
            gone.close_hand()
        with pytest.raises(ValueError, match="not a hand-loop command"):
            kept.post("close")  # type: ignore[arg-type]
        kept.close_hand()
        wait_for(lambda: kept.status.modes != ("idle",) * 3, 30, "the kept hand closing")
        wait_class(hands, 0.1)
        assert kept.status.running and not kept.status.fault
    finally:
        hands.close()
