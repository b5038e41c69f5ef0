"""Camera backends behind one small Protocol: picamera2, v4l2, replay, sim."""
