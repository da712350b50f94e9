"""Engine stage: the explicit time loop on plain arrays. Never imports pydantic or yaml."""
