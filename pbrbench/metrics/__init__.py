"""Scores: each function compares an estimate with the ground truth and returns a float or a map."""
