"""friction_models."""
