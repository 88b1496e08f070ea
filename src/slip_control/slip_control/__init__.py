"""slip_control."""
