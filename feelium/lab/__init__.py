"""feelium.lab."""
