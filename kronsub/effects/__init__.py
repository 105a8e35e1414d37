"""Effects: the named loads of a model (gravity, loads, springs, dampers); see base.py."""
