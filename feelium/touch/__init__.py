"""Rear-camera shadow pipeline: reference, depth, gates, fingertip, tracker."""
