"""feelium.lab.http."""
