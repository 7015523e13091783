"""`python -m bench` (make bench): every benchmark, one after the other."""

from bench import lockstep

if __name__ == "__main__":
    lockstep.main([])
