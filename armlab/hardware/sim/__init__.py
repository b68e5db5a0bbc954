"""The simulation every family shares: the geared motor at the base of every servo's
firmware model (``servo_motor.py``; each family's model is its folder's ``firmware.py``),
the arm's rigid body and its servos stepped at a fixed step (``plant.py``, its step
``plant_step.py``) and the thesis's hand (``hand_plant.py``, N at once
``batched_hand.py``). The simulated arms over them are the families' own
(``families/<family>/sim_backend.py``)."""
