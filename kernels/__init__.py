"""All of pbrwarp's Warp code, one concern per module.

Every module here compiles with ``enable_backward=False``: pbrwarp needs no gradients, and the
backward pass would double compile time.
"""
