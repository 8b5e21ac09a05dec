"""Method III: the stated tolerance, normalised curiosity and the PID multiplier, with its amendments."""
