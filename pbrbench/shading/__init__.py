"""Forward models in NumPy: analytic surfaces, local Lambertian shading, closed-form irradiance.

These are the exact references the renderer and the inference algorithms are checked against.
"""
