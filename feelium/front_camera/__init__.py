"""The front (fisheye) camera service: the wearer's eyes."""
