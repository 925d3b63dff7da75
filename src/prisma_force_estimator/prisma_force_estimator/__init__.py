"""Neural taxel-to-wrench estimation: training, evaluation and inference node."""
