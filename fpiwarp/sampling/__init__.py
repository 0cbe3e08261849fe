"""The host sampling reference: the contract every kernel's sampler cites.

* :mod:`.sampler`: sampling an image at real (x, y) positions (orders 0, 1
  and 3, the four border modes, the pole rule), in float64;
* :mod:`.antialias`: the antialiased sampler, a footprint from the map's
  analytic Jacobian;
* :mod:`.positions`: where each output pixel samples the source.

The numbers kernels compare with (modes, limits, tap spacings) live in the
parameter block's contract, :mod:`fpiwarp.block.sampling_rules`, so that
``fpiwarp.block.codegen`` can write them for every kernel language.
"""
