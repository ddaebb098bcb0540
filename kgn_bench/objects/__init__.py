"""Importing objects: a user's mesh or a packaged set of meshes into object folders (``shapes.mesh_object``)."""
