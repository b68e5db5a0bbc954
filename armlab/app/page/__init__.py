"""The page's pieces every lesson uses: the arm drawn from its URDF, the camera, number
inputs that refuse bad values, drags handled in the order the page sent them, the plainer
look, collapsed panels, live charts, the frame publisher, E-STOP first, and the text
sizes (normal or projector)."""
