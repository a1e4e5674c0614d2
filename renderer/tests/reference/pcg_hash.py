"""Reference values of the PCG hash used by the ca chain's noise (renderer/src/ca/mod.rs,
renderer/src/gpu/artifacts.wgsl), transcribed from Jarzynski & Olano, "Hash Functions for GPU
Rendering", JCGT 9(3), 2020, listing `pcg`:

    uint pcg(uint v) {
        uint state = v * 747796405u + 2891336453u;
        uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
        return (word >> 22u) ^ word;
    }

with numpy's uint32 arithmetic (wrapping). Run: python3 pcg_hash.py
"""
import numpy as np

def pcg(v):
    with np.errstate(over="ignore"):
        state = np.uint32(v) * np.uint32(747796405) + np.uint32(2891336453)
        word = ((state >> ((state >> np.uint32(28)) + np.uint32(4))) ^ state) * np.uint32(277803737)
        return int((word >> np.uint32(22)) ^ word)

print([pcg(v) for v in range(4)])
