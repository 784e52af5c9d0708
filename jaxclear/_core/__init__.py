"""The ground floor: errors, argument checks, smooth primitives, planar geometry, registries,
progress bars and the compiled-program store. Imports nothing else of jaxclear; every other floor
may import it (modules are imported by their own names, this file re-exports nothing)."""
