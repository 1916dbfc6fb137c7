"""What a run leaves in a temporary folder, besides what driftfmu keeps there by design."""
import os

#: driftfmu's private folder (simulations/folders.py), kept from run to run: its compiled
#: libraries (simulations/trust.py) stay; its destination locks go with each commit.
PRIVATE = "driftfmu-%d" % os.geteuid()


def left_in(tmp):
    """The names left in the temporary folder ``tmp``: everything but the private folder, and
    in the private folder everything but its ``libraries`` and an empty ``locks`` folder
    (named ``driftfmu-<uid>/<name>``)."""
    left = []
    for name in sorted(os.listdir(tmp)):
        path = os.path.join(tmp, name)
        if name != PRIVATE or os.path.islink(path) or not os.path.isdir(path):
            left.append(name)
            continue
        for inner in sorted(os.listdir(path)):
            if inner == "libraries" or (inner == "locks"
                                        and not os.listdir(os.path.join(path, inner))):
                continue
            left.append("%s/%s" % (name, inner))
    return left
