"""The warp engine: energy terms, sparse solver, content-free and content-aware warps."""
