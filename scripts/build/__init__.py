"""Builders of the bundled assets and of the Blender extension."""
