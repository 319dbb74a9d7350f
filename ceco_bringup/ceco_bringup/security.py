"""``ceco security create-keystore DIR``: an SROS2 keystore for the ceco stack, with topic access control.

Writes the layout ``ros2 security create_keystore`` + ``create_enclave`` write (sros2, Jazzy), so
``ROS_SECURITY_KEYSTORE=DIR`` with ``--enclave /ceco/<node>`` (the launch files' ``security:=true``)
uses it as any SROS2 keystore::

    DIR/public/identity_ca.cert.pem, permissions_ca.cert.pem     the two CAs (self-signed, EC P-256)
    DIR/private/identity_ca.key.pem, permissions_ca.key.pem
    DIR/enclaves/governance.xml, governance.p7s                 signed by the permissions CA
    DIR/enclaves/ceco/<node>/cert.pem, key.pem                  identity CN=/ceco/<node>, by the identity CA
    DIR/enclaves/ceco/<node>/permissions.xml, permissions.p7s   signed by the permissions CA
    DIR/enclaves/ceco/<node>/identity_ca.cert.pem, permissions_ca.cert.pem, governance.p7s   (links)

Unlike sros2's default wildcard permissions, the grants are ceco's policy: only the controller
enclaves (mpc_node, baseline_node) may publish ``hvac/command`` (in any namespace); every enclave
may publish and subscribe everything else. The governance (sros2's default) requires authenticated
participants, encrypts discovery, liveliness and data, and enforces read and write access control
on every topic. Signatures are S/MIME (PKCS#7 detached, text), as DDS Security and sros2 use.
The module needs ``cryptography`` (and no ROS).
"""

from __future__ import annotations

import argparse
import datetime
import os
import sys
from pathlib import Path
from xml.sax.saxutils import escape

__all__ = ['CONTROLLER_ENCLAVES', 'ENCLAVES', 'COMMAND_TOPICS', 'create_keystore', 'main']

ENCLAVES = ('/ceco/preview_node', '/ceco/mpc_node', '/ceco/baseline_node', '/ceco/plant_node', '/ceco/ceco')
"""One enclave per node (``--enclave /ceco/<node>``) and one for the ``ceco`` tools (recorder, player)."""
CONTROLLER_ENCLAVES = ('/ceco/mpc_node', '/ceco/baseline_node')
"""The enclaves allowed to publish the A/C command."""
COMMAND_TOPICS = ('rt/hvac/command', 'rt/*/hvac/command')
"""``hvac/command`` as a DDS topic name (ROS prefix ``rt/``), at the root and in any namespace."""
DOMAINS = '<domains><id_range><min>0</min><max>232</max></id_range></domains>'
VALID_DAYS = 3650

GOVERNANCE = f"""<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"
    xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_governance.xsd">
  <domain_access_rules>
    <domain_rule>
      {DOMAINS}
      <allow_unauthenticated_participants>false</allow_unauthenticated_participants>
      <enable_join_access_control>true</enable_join_access_control>
      <discovery_protection_kind>ENCRYPT</discovery_protection_kind>
      <liveliness_protection_kind>ENCRYPT</liveliness_protection_kind>
      <rtps_protection_kind>SIGN</rtps_protection_kind>
      <topic_access_rules>
        <topic_rule>
          <topic_expression>*</topic_expression>
          <enable_discovery_protection>true</enable_discovery_protection>
          <enable_liveliness_protection>true</enable_liveliness_protection>
          <enable_read_access_control>true</enable_read_access_control>
          <enable_write_access_control>true</enable_write_access_control>
          <metadata_protection_kind>ENCRYPT</metadata_protection_kind>
          <data_protection_kind>ENCRYPT</data_protection_kind>
        </topic_rule>
      </topic_access_rules>
    </domain_rule>
  </domain_access_rules>
</dds>
"""


def permissions_xml(enclave: str, not_before: datetime.datetime, not_after: datetime.datetime) -> str:
    """The DDS permissions of ``enclave``: rules are matched in order, so the deny rule comes first."""
    topics = ''.join(f'<topic>{escape(t)}</topic>' for t in COMMAND_TOPICS)
    deny = (
        ''
        if enclave in CONTROLLER_ENCLAVES
        else f'\n      <deny_rule>{DOMAINS}<publish><topics>{topics}</topics></publish></deny_rule>'
    )
    everything = '<topics><topic>*</topic></topics>'
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"
    xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_permissions.xsd">
  <permissions>
    <grant name="{escape(enclave)}">
      <subject_name>CN={escape(enclave)}</subject_name>
      <validity><not_before>{not_before:%Y-%m-%dT%H:%M:%S}</not_before><not_after>{not_after:%Y-%m-%dT%H:%M:%S}</not_after></validity>{deny}
      <allow_rule>{DOMAINS}<publish>{everything}</publish><subscribe>{everything}</subscribe></allow_rule>
      <default>DENY</default>
    </grant>
  </permissions>
</dds>
"""


def _key_and_cert(subject: str, now: datetime.datetime, issuer=None):
    """An EC P-256 key (DDS Security 9.3.1) and its certificate, self-signed (a CA) or by ``issuer`` (cert, key)."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import NameOID

    key = ec.generate_private_key(ec.SECP256R1())
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, subject)])
    issuer_cert, issuer_key = issuer if issuer else (None, key)
    cert = (
        x509.CertificateBuilder()
        .subject_name(name)
        .issuer_name(issuer_cert.subject if issuer_cert else name)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - datetime.timedelta(days=1))
        .not_valid_after(now + datetime.timedelta(days=VALID_DAYS))
        .add_extension(x509.BasicConstraints(ca=issuer is None, path_length=1 if issuer is None else None), True)
        .sign(issuer_key, hashes.SHA256())
    )
    return cert, key


def _write_pem(path: Path, cert=None, key=None) -> None:
    from cryptography.hazmat.primitives import serialization

    if cert is not None:
        path.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    else:
        path.write_bytes(
            key.private_bytes(
                serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption()
            )
        )
        path.chmod(0o600)


def _smime_sign(text: str, ca) -> bytes:
    """``text`` signed by the CA ``(cert, key)``: S/MIME, detached, text/plain (sros2's format)."""
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.serialization import pkcs7

    builder = pkcs7.PKCS7SignatureBuilder().set_data(text.encode()).add_signer(ca[0], ca[1], hashes.SHA256())
    return builder.sign(serialization.Encoding.SMIME, [pkcs7.PKCS7Options.Text, pkcs7.PKCS7Options.DetachedSignature])


def _link(target: Path, link: Path) -> None:
    link.unlink(missing_ok=True)
    link.symlink_to(os.path.relpath(target, link.parent))


def create_keystore(root: Path, enclaves=ENCLAVES, now: datetime.datetime | None = None) -> list[Path]:
    """Write the keystore at ``root`` (a new or empty directory); return the enclave directories."""
    root = Path(root)
    if root.exists() and any(root.iterdir()):
        raise FileExistsError(f'{root} exists and is not empty: choose a new directory')
    now = now or datetime.datetime.now(datetime.UTC).replace(tzinfo=None, microsecond=0)
    public, private, enclaves_dir = root / 'public', root / 'private', root / 'enclaves'
    for d in (public, private, enclaves_dir):
        d.mkdir(parents=True, exist_ok=True)
    private.chmod(0o700)
    cas = {}
    for role in ('identity', 'permissions'):
        cas[role] = _key_and_cert(f'ceco {role} CA', now)
        _write_pem(public / f'{role}_ca.cert.pem', cert=cas[role][0])
        _write_pem(private / f'{role}_ca.key.pem', key=cas[role][1])
    (enclaves_dir / 'governance.xml').write_text(GOVERNANCE)
    (enclaves_dir / 'governance.p7s').write_bytes(_smime_sign(GOVERNANCE, cas['permissions']))
    made = []
    for enclave in enclaves:
        d = enclaves_dir / enclave.strip('/')
        d.mkdir(parents=True, exist_ok=True)
        cert, key = _key_and_cert(enclave, now, issuer=cas['identity'])
        _write_pem(d / 'cert.pem', cert=cert)
        _write_pem(d / 'key.pem', key=key)
        text = permissions_xml(enclave, now - datetime.timedelta(days=1), now + datetime.timedelta(days=VALID_DAYS))
        (d / 'permissions.xml').write_text(text)
        (d / 'permissions.p7s').write_bytes(_smime_sign(text, cas['permissions']))
        for name in ('identity_ca.cert.pem', 'permissions_ca.cert.pem'):
            _link(public / name, d / name)
        _link(enclaves_dir / 'governance.p7s', d / 'governance.p7s')
        made.append(d)
    return made


def main(argv=None) -> int:
    """``ceco security create-keystore DIR``."""
    ap = argparse.ArgumentParser(prog='ceco security', description=__doc__.split('\n\n')[0])
    sub = ap.add_subparsers(dest='command', required=True)
    ks = sub.add_parser('create-keystore', help='write an SROS2 keystore with the ceco enclaves and access control')
    ks.add_argument('dir', type=Path, help='a new (or empty) directory')
    args = ap.parse_args(argv)
    try:
        made = create_keystore(args.dir)
    except FileExistsError as err:  # (ours: the directory is not empty)
        print(f'ceco security: {err}', file=sys.stderr, flush=True)
        return 2
    except OSError as err:  # a path under a file, no permission, a full disk: in words, on stderr
        where = f' ({err.filename})' if err.filename else ''
        print(f'ceco security: cannot write the keystore {args.dir}: {err.strerror}{where}', file=sys.stderr)
        return 2
    print(f'keystore {args.dir}: enclaves {", ".join(ENCLAVES)}; only {", ".join(CONTROLLER_ENCLAVES)} may publish')
    print(f'hvac/command. Use: ros2 launch ceco_bringup ceco.launch.py security:=true keystore:={args.dir.resolve()}')
    return 0 if made else 1
