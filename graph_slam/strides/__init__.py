"""The stride stage: a session's streams on the camera clock, cut into strides at foot strikes.

One place for each job every later stage needs: the streams shifted onto the camera clock
(:mod:`.streams`), joint angles at any time ``q(t)``, the up vector, and the per-stride
reference (ground truth in each stride's frame) that evaluation and benchmarks score against.
"""
