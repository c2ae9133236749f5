"""Studies built on the models and the engine (the thesis' topology study), without the CLI."""
