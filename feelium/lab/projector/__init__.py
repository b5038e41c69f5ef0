"""feelium.lab.projector."""
