"""Everything MuJoCo-specific: building the model, the callbacks, running it."""
