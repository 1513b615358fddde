"""Live AU streams: the FAS remote player's wire formats, player and sender (no bpy)."""
