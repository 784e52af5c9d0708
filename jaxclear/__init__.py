"""jaxclear: differentiable planar multibody dynamics with revolute clearance joints."""

import jax

jax.config.update("jax_enable_x64", True)
