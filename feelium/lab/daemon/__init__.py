"""feelium.lab.daemon."""
