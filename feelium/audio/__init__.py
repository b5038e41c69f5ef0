"""Speech between wearer and room: ALSA on the blimp, fakes elsewhere."""
