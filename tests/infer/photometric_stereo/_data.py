"""Shared data of the photometric-stereo tests."""

import numpy as np

# The chapter's five sources (Fig 1.13): one along the view, four oblique ones.
CHAPTER_LIGHTS = np.array([[0, 0, 1], [1, 0, 1.5], [-1, 0, 1.5], [0, 1, 1.5], [0, -1, 1.5]], float)
CHAPTER_LIGHTS /= np.linalg.norm(CHAPTER_LIGHTS, axis=1, keepdims=True)


def ang(a, b):
    """Angle in degrees, by atan2 (exact near 0, where arccos of a rounded dot is ~1e-6 deg off)."""
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1)))
