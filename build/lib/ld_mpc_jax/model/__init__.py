"""The model: encoder, proposals, dynamics, objective and critics, actor, search, multi-task conditioning; config checks read from their registries."""
