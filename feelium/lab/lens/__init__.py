"""feelium.lab.lens: fitting the front fisheye's lens model (``feelium calibrate lens``)."""
