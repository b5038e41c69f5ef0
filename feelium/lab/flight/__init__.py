"""feelium.lab.flight."""
