"""The simulation: the geared motor every servo's firmware model shares (each family's
model is its folder's ``firmware.py``), the arm's rigid body (one arm, and N arms stepped
together), the thesis's hand and the seed 003 quadruped."""
