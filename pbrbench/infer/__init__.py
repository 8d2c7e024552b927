"""The NumPy inference package: algorithms that run on linear images, rendered or real.

Imports only NumPy and SciPy (never mitsuba or drjit), so it works on real photographs.
"""
