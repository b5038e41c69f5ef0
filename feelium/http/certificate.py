"""The SHA-256 fingerprint of the daemon's TLS certificate: what a headset pins instead of trusting a CA.

A blimp's certificate is self-signed (no CA knows a ``.local`` name), so a
client must pin exactly that certificate; ``feelium pair`` prints the
fingerprint in the form the visionOS guide compares (the SHA-256 of the DER
bytes, as ``openssl x509 -outform der | sha256sum`` gives it), and checks that
the running daemon serves the same one (a replaced file is used only after a
restart).
"""

from __future__ import annotations

import hashlib
import ssl
from pathlib import Path


def der_fingerprint(der: bytes) -> str:
    """``AB:CD:...``: the SHA-256 of a certificate's DER bytes, in colon-separated upper-case hex."""
    return ":".join(f"{b:02X}" for b in hashlib.sha256(der).digest())


def pem_file_fingerprint(path: str | Path) -> str:
    """The fingerprint of the first certificate in a PEM file (the leaf, as ``tls_cert`` holds it)."""
    text = Path(path).read_text(encoding="ascii", errors="replace")
    end = "-----END CERTIFICATE-----"
    if "-----BEGIN CERTIFICATE-----" not in text or end not in text:
        raise ValueError(f"{path}: no PEM certificate in it")
    first = text[text.index("-----BEGIN CERTIFICATE-----") : text.index(end) + len(end)]
    return der_fingerprint(ssl.PEM_cert_to_DER_cert(first))


def served_fingerprint(host: str, port: int, timeout_s: float = 5.0) -> str:
    """The fingerprint of the certificate a TLS server presents (not verified: this is what we compare)."""
    return der_fingerprint(ssl.PEM_cert_to_DER_cert(ssl.get_server_certificate((host, port), timeout=timeout_s)))
