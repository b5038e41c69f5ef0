"""feelium.lab.sim."""
