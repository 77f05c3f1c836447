"""The return map: stride outcomes, the order-8 flows, the compiled kernels and their
driver, batches, the adaptive event map (reference and fallback), code generation and its
disk cache, and the sampled motion of strides."""
