"""feelium.lab.thermal."""
