"""Learning: the loss as named terms, the train state and its jitted update, checkpoints."""
