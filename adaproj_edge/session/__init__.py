"""Recorded sessions: MCAP recorder and reader, replay clock."""
