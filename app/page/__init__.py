"""The page's pieces every lesson uses: the arm drawn from its URDF, the camera, number
inputs that refuse bad values, the plainer look, collapsed panels, live charts, the frame
publisher, E-STOP first, and the text sizes (normal or projector)."""
