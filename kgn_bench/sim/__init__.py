"""The simulated world: scene composition, camera, rendering, placement and collision labelling."""
