"""The simulation: each servo's firmware and motor, the arm's rigid body (one arm, and N arms
stepped together), the thesis's hand and the seed 003 quadruped."""
