"""The tracking benchmark: a model's inverse driving the virtual DEA.

plant (the physics + sensor, stepped with a controller in the loop), references,
controllers (linear gain, model inverse, PI), run (every controller on every
reference), report (compensation.md, figures, JSON).
"""
