"""What the skin shows: renderer, calibration, interaction engine."""
