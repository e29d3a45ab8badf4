"""Online training's settings, acting schedules and checks (`config.online`)."""
