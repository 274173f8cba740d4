"""What the tests need where the lent GPU machine lacks it: it has no example-robot-data, so the Panda comes from a
URDF carried beside the checkout (under .gpu/ in example-robot-data's own folders, or the file $PANDA_URDF names)."""

import os
from importlib import metadata

CARRIED_URDF = ".gpu/example-robot-data/robots/panda_description/urdf/panda.urdf"


def panda_chain() -> dict:
    """TrainConfig's options naming the Panda: by name where example-robot-data is installed, else by its URDF."""
    try:
        metadata.distribution("example-robot-data")
        return {"robot": "panda"}
    except metadata.PackageNotFoundError:
        return {"urdf": os.environ.get("PANDA_URDF", CARRIED_URDF), "ee_link": "panda_hand"}
