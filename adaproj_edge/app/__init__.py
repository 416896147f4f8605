"""The device runtime: states, button, motion, re-estimation, scheduling."""
