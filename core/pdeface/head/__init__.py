"""The user's whole head: its parts, and AU keys on every one of its vertices.

:func:`pdeface.head.parts.classify_parts` tells skin from eyeballs, teeth and
lashes; :class:`pdeface.head.bind.HeadBinding` carries the PDE face's motion
to all of the mesh.
"""
