"""A plug-in written against a module path from before cosim's regroup into layers
(``cosim.records``, now ``cosim.core.records``): loading it must name the new path."""

from cosim.records import Command  # type: ignore[import-not-found]  # the old path, on purpose


class Old:
    def step(self, t_s: float, estimate: object, reference: object) -> Command:
        return Command(t_s, 0.0, 0.0)
