"""What machine a benchmark ran on, for the figures it prints."""
import platform


def cpu():
    """The CPU's model name (Linux), or what the platform says."""
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"
