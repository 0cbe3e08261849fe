"""The ``"numpy"`` backend: the float64 reference (:mod:`.backend`)."""
