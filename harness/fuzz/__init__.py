"""Generated input at the program's boundaries and how each answer is judged (run a fixed
number of examples by ``tests/fuzz``, for as long as asked by ``benchmarks/fuzz.py``)."""
