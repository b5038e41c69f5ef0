"""Speech between wearer and room: ALSA on the blimp, simulated (sim) elsewhere."""
