"""Runs and caching: digests of binaries and inputs, the keys of cached results."""
import hashlib


def file_digest(path, algorithm="sha256"):
    """Hex digest of a file's bytes (read in 1 MiB blocks)."""
    digest = hashlib.new(algorithm)
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()
