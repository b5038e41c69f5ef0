"""feelium.lab.touch."""
