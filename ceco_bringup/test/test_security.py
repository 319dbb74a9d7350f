"""`ceco security create-keystore`: the SROS2 keystore's certificates verify, the permissions and the
governance are S/MIME-signed by the permissions CA (checked with openssl, as Fast DDS's security
plugins do), and only the controller enclaves may publish hvac/command. DDS security itself cannot
run here (the pip wheels' Fast DDS is built without it; docs/ros.md)."""

import fnmatch
import subprocess
import xml.etree.ElementTree as ET

import pytest

from ceco_bringup import security

pytestmark = pytest.mark.skipif(
    subprocess.run(['openssl', 'version'], capture_output=True, check=False).returncode != 0, reason='no openssl'
)


@pytest.fixture(scope='module')
def keystore(tmp_path_factory):
    root = tmp_path_factory.mktemp('keys') / 'ceco_keys'
    assert security.main(['create-keystore', str(root)]) == 0
    return root


def _openssl(*args):
    return subprocess.run(['openssl', *map(str, args)], capture_output=True, text=True, check=False)


def test_layout_is_sros2s(keystore):
    assert sorted(p.name for p in (keystore / 'public').iterdir()) == [
        'identity_ca.cert.pem',
        'permissions_ca.cert.pem',
    ]
    assert sorted(p.name for p in (keystore / 'private').iterdir()) == ['identity_ca.key.pem', 'permissions_ca.key.pem']
    assert (keystore / 'private' / 'identity_ca.key.pem').stat().st_mode & 0o077 == 0  # keys private
    for enclave in security.ENCLAVES:
        d = keystore / 'enclaves' / enclave.strip('/')
        names = {'cert.pem', 'key.pem', 'permissions.xml', 'permissions.p7s', 'governance.p7s'}
        names |= {'identity_ca.cert.pem', 'permissions_ca.cert.pem'}
        assert {p.name for p in d.iterdir()} == names, enclave
        assert (d / 'governance.p7s').read_bytes() == (keystore / 'enclaves' / 'governance.p7s').read_bytes()


def test_certificates_verify_against_the_identity_ca_only(keystore):
    public = keystore / 'public'
    for enclave in security.ENCLAVES:
        cert = keystore / 'enclaves' / enclave.strip('/') / 'cert.pem'
        ok = _openssl('verify', '-CAfile', public / 'identity_ca.cert.pem', cert)
        assert ok.returncode == 0 and ok.stdout.strip().endswith(': OK'), ok.stdout + ok.stderr
        assert _openssl('verify', '-CAfile', public / 'permissions_ca.cert.pem', cert).returncode != 0
        subject = _openssl('x509', '-in', cert, '-noout', '-subject', '-nameopt', 'RFC2253').stdout
        assert subject.strip() == f'subject=CN={enclave}'
        key = keystore / 'enclaves' / enclave.strip('/') / 'key.pem'  # the key is the certificate's
        assert (
            _openssl('pkey', '-in', key, '-pubout').stdout == _openssl('x509', '-in', cert, '-noout', '-pubkey').stdout
        )


def _smime_verify(signed, ca):
    return _openssl('smime', '-verify', '-text', '-in', signed, '-CAfile', ca, '-purpose', 'any')


def test_permissions_and_governance_are_signed_by_the_permissions_ca(keystore, tmp_path):
    ca = keystore / 'public' / 'permissions_ca.cert.pem'
    wrong = keystore / 'public' / 'identity_ca.cert.pem'
    gov = keystore / 'enclaves' / 'governance.p7s'
    done = _smime_verify(gov, ca)
    assert done.returncode == 0 and done.stdout.replace('\r\n', '\n') == security.GOVERNANCE
    for enclave in security.ENCLAVES:
        d = keystore / 'enclaves' / enclave.strip('/')
        done = _smime_verify(d / 'permissions.p7s', ca)
        assert done.returncode == 0, done.stderr
        assert done.stdout.replace('\r\n', '\n') == (d / 'permissions.xml').read_text()
        assert _smime_verify(d / 'permissions.p7s', wrong).returncode != 0  # not by the identity CA
    # a permissions document altered after signing does not verify
    forged = tmp_path / 'forged.p7s'
    forged.write_bytes((d / 'permissions.p7s').read_bytes().replace(b'<deny_rule>', b'<allow_rule>'))
    assert b'<allow_rule>' in forged.read_bytes() and _smime_verify(forged, ca).returncode != 0


def _may_publish(permissions: ET.Element, subject: str, topic: str) -> bool:
    """DDS Security 9.4.1.3: the grant of the subject, its rules in order, the first matching one decides."""
    (grant,) = [g for g in permissions.iter('grant') if g.findtext('subject_name') == subject]
    for rule in grant:
        if rule.tag in ('allow_rule', 'deny_rule'):
            for t in rule.findall('publish/topics/topic'):
                if fnmatch.fnmatchcase(topic, t.text):
                    return rule.tag == 'allow_rule'
    return grant.findtext('default') == 'ALLOW'


@pytest.mark.parametrize('topic', ['rt/hvac/command', 'rt/veh1/hvac/command', 'rt/fleet/veh7/hvac/command'])
def test_only_the_controller_enclaves_may_publish_the_command(keystore, topic):
    allowed = set()
    for enclave in security.ENCLAVES:
        doc = ET.parse(keystore / 'enclaves' / enclave.strip('/') / 'permissions.xml').getroot()
        if _may_publish(doc, f'CN={enclave}', topic):
            allowed.add(enclave)
        assert _may_publish(doc, f'CN={enclave}', 'rt/cabin/state')  # everything else stays open
        assert _may_publish(doc, f'CN={enclave}', 'rt/veh1/v2x/weather_preview')
    assert allowed == set(security.CONTROLLER_ENCLAVES) == {'/ceco/mpc_node', '/ceco/baseline_node'}


def test_a_keystore_is_never_written_over(keystore, capsys):
    assert security.main(['create-keystore', str(keystore)]) == 2
    said = capsys.readouterr()
    assert 'exists and is not empty' in said.err and not said.out  # an error goes to stderr


def test_a_keystore_that_cannot_be_written_is_one_line_in_words(tmp_path, capsys):
    """A path under a file: `ceco security: [Errno 20] Not a directory: ...` on stdout before; now one line on
    stderr naming the keystore, what went wrong and where, exit status 2."""
    (tmp_path / 'file').write_text('')
    assert security.main(['create-keystore', str(tmp_path / 'file' / 'keys')]) == 2
    said = capsys.readouterr()
    assert not said.out and said.err.count('\n') == 1 and 'Errno' not in said.err
    assert said.err.startswith(
        f"ceco security: cannot write the keystore {tmp_path / 'file' / 'keys'}: Not a directory"
    )
