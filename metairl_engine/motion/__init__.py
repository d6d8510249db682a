"""Human motion: COP recordings cut into demonstrations, force-plate arithmetic, kinematic and learned readouts.

numpy only (scipy and matplotlib imported inside the functions that need them), so the API process can use it.
"""
