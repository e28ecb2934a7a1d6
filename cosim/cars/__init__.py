"""Published cars as cosim plants, each with the belief ``cosim identify`` finds for it
(``car: NAME`` in a scenario, ``--set car=NAME``; written by ``tools/commonroad_cars.py``)."""
