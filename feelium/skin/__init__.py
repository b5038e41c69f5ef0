"""The skin: where a camera pixel lies on the envelope (u, v), its named regions, and the camera-to-projector map.

Shared by the touch service (which annotates events), the projector (which
answers at the touched spot) and the interaction rules, so one definition of
each lives here and none of them imports another.
"""
