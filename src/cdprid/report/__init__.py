"""Report layer: every figure and table of every feature lives here (one module per feature).

Features compute; this layer draws. Nothing in the core or feature layers imports matplotlib.
"""
