//! The signed documents of a keystore (governance, permissions: S/MIME with a CMS SignedData)
//! interoperate with OpenSSL, which other DDS implementations and operators use to sign and
//! check them: a document `rl keys` signed verifies with `openssl smime -verify`, and one
//! OpenSSL signed with the keystore's CA verifies in RL's start-up check (`Keystore::open`),
//! while an altered one or one signed by another key is refused by both.
//!
//! Needs Debian's `openssl` command (`.ci/run` installs it); fails without it.
#![cfg(feature = "security")]

mod support;

use rl_layer::config::Dds;
use rl_layer::security::documents::Grantee;
use rl_layer::security::keys::{self, Validity};
use rl_layer::security::Keystore;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use support::tempdir::Dir;

fn openssl(args: &[&str]) -> Output {
    Command::new("openssl")
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("cannot run openssl (apt install openssl): {e}"))
}

fn text(path: &Path) -> &str {
    path.to_str().expect("a UTF-8 path")
}

/// OpenSSL refused a document; what it said.
#[derive(Debug)]
struct Refused {
    stderr: String,
}

impl std::fmt::Display for Refused {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "openssl: {}", self.stderr.trim())
    }
}

/// `openssl smime -verify` of `signed` against `ca`; the verified document on success, what
/// OpenSSL said otherwise.
fn openssl_verify(signed: &Path, ca: &Path, out: &Path) -> Result<String, Refused> {
    let output = openssl(&[
        "smime",
        "-verify",
        "-in",
        text(signed),
        "-CAfile",
        text(ca),
        "-out",
        text(out),
    ]);
    if output.status.success() {
        Ok(std::fs::read_to_string(out).expect("openssl wrote the document"))
    } else {
        Err(Refused {
            stderr: String::from_utf8_lossy(&output.stderr).into_owned(),
        })
    }
}

/// `openssl smime -sign -text` of `document` with `cert` and `key` into `signed`, as the
/// DDS Security specification's examples sign governance and permissions documents.
fn openssl_sign(document: &Path, cert: &Path, key: &Path, signed: &Path) {
    let output = openssl(&[
        "smime",
        "-sign",
        "-text",
        "-md",
        "sha256",
        "-in",
        text(document),
        "-signer",
        text(cert),
        "-inkey",
        text(key),
        "-out",
        text(signed),
    ]);
    assert!(
        output.status.success(),
        "openssl smime -sign: {}",
        String::from_utf8_lossy(&output.stderr)
    );
}

/// A CA with controller 1's keystore in `dir/c1`.
fn keystore(dir: &Path) -> PathBuf {
    let dds = Dds::default();
    keys::init(dir, &dds, Validity::from_now(30)).expect("rl keys init");
    keys::add(dir, &dds, &Grantee::Controller(1), Validity::from_now(30)).expect("rl keys add")
}

#[test]
fn documents_rl_signs_verify_with_openssl() {
    let dir = Dir::new("smime-rl-signs");
    let c1 = keystore(&dir.0);
    let ca = dir.0.join("ca.cert.pem");
    let out = dir.0.join("verified.xml");
    for document in [c1.join("governance.p7s"), c1.join("permissions.p7s")] {
        let verified = openssl_verify(&document, &ca, &out)
            .unwrap_or_else(|e| panic!("openssl refused {}: {e}", document.display()));
        assert!(verified.contains("<dds"), "{verified}");
    }
    // OpenSSL is not lenient: the same document altered fails its check.
    let governance = std::fs::read_to_string(c1.join("governance.p7s")).unwrap();
    let altered = dir.0.join("altered.p7s");
    std::fs::write(
        &altered,
        governance.replace(
            "<enable_join_access_control>true",
            "<enable_join_access_control>false",
        ),
    )
    .unwrap();
    assert!(openssl_verify(&altered, &ca, &out).is_err());
}

#[test]
fn documents_openssl_signs_verify_in_rl() {
    let dir = Dir::new("smime-openssl-signs");
    let c1 = keystore(&dir.0);
    let ca = dir.0.join("ca.cert.pem");
    let ca_key = dir.0.join("ca.key.pem");
    let plain = dir.0.join("plain");
    std::fs::create_dir_all(&plain).unwrap();
    for name in ["governance", "permissions"] {
        let signed = c1.join(format!("{name}.p7s"));
        let document = plain.join(format!("{name}.xml"));
        openssl_verify(&signed, &ca, &document).expect("openssl reads RL's document");
        openssl_sign(&document, &ca, &ca_key, &signed);
    }
    assert!(std::fs::read_to_string(c1.join("governance.p7s"))
        .unwrap()
        .contains("This is an S/MIME signed message"));
    Keystore::open(&c1, false).expect("RL accepts the documents OpenSSL signed");

    // Altered after OpenSSL signed it: refused, naming the file.
    let governance = support::keys::alter_governance(&c1);
    let error = Keystore::open(&c1, false).expect_err("an altered document is refused");
    assert!(
        error.file == governance && error.problem.contains("altered"),
        "{error}"
    );

    // Signed by OpenSSL with a key that is not the CA's: refused.
    let stranger_key = dir.0.join("stranger.key.pem");
    let stranger_cert = dir.0.join("stranger.cert.pem");
    let made = openssl(&[
        "req",
        "-x509",
        "-newkey",
        "ec",
        "-pkeyopt",
        "ec_paramgen_curve:P-256",
        "-nodes",
        "-subj",
        "/CN=stranger",
        "-days",
        "1",
        "-keyout",
        text(&stranger_key),
        "-out",
        text(&stranger_cert),
    ]);
    assert!(made.status.success(), "{made:?}");
    openssl_sign(
        &plain.join("governance.xml"),
        &stranger_cert,
        &stranger_key,
        &governance,
    );
    let error = Keystore::open(&c1, false).expect_err("a stranger's signature is refused");
    assert!(
        error.file == governance && error.problem.contains("not the CA's"),
        "{error}"
    );
}
