"""slip_velocity_sensor."""
