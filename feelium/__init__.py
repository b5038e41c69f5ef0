"""Feelium: onboard software of a touchable telepresence blimp."""

__version__ = "0.1.0"
