//! Making keystores (`rl keys init`, `rl keys add`): the CA, the governance document, and
//! each participant's key, certificate and permissions, all ECDSA P-256 (what RustDDS and the
//! DDS Security builtin plugins accept), in pure Rust.
//!
//! `init` writes the CA's key and certificate and the governance document to the directory.
//! `add` writes one participant's keystore to a subdirectory (`c<id>` for a controller, the
//! name for an application): its own `key.pem`, `cert.pem` (subject `CN=rl-controller-<id>`
//! or `CN=rl-app-<name>`) and `permissions.p7s`, plus copies of `ca.cert.pem` and the
//! governance document, so that one directory is what a machine needs (`[security]
//! keystore`). The CA key never leaves the directory `init` made. (OpenSSL is not involved:
//! RustDDS itself needs it only for its Diffie-Hellman exchange.)

use super::certificate::Certificate;
use super::documents::{self, Grantee};
use super::pem;
use super::{smime, CA_CERT, CA_KEY, CERT, GOVERNANCE, KEY, PERMISSIONS};
use crate::config::Dds;
use der::Decode;
use rcgen::{
    BasicConstraints, CertificateParams, DnType, IsCa, KeyPair, KeyUsagePurpose, SerialNumber,
    PKCS_ECDSA_P256_SHA256,
};
use std::path::{Path, PathBuf};
use time::{Duration, OffsetDateTime};

const CA_COMMON_NAME: &str = "rl-ca";

/// A failure to make a keystore, naming the file.
#[derive(Debug, thiserror::Error)]
#[error("{}: {problem}", path.display())]
pub struct KeysError {
    /// The file or directory that could not be read, written or used.
    pub path: PathBuf,
    /// What went wrong with it.
    pub problem: String,
}

fn fail(path: &Path, problem: impl std::fmt::Display) -> KeysError {
    KeysError {
        path: path.to_path_buf(),
        problem: problem.to_string(),
    }
}

/// When a certificate is valid: from `not_before` for `days` days.
#[derive(Clone, Copy, Debug)]
pub struct Validity {
    /// Start of validity (UTC).
    pub not_before: OffsetDateTime,
    /// How long the certificates are valid, in days from `not_before`.
    pub days: u32,
}

impl Validity {
    /// From now (less a minute, for clocks slightly behind) for `days` days.
    pub fn from_now(days: u32) -> Validity {
        Validity {
            not_before: OffsetDateTime::now_utc() - Duration::minutes(1),
            days,
        }
    }

    fn not_after(&self) -> OffsetDateTime {
        self.not_before + Duration::days(i64::from(self.days))
    }
}

fn write(path: &Path, contents: &str, private: bool) -> Result<(), KeysError> {
    std::fs::write(path, contents).map_err(|e| fail(path, format!("cannot write: {e}")))?;
    if private {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o600))
            .map_err(|e| fail(path, format!("cannot make it private: {e}")))?;
    }
    Ok(())
}

fn read(path: &Path) -> Result<String, KeysError> {
    std::fs::read_to_string(path).map_err(|e| fail(path, format!("cannot read: {e}")))
}

fn ca_params(validity: Validity) -> CertificateParams {
    let mut params = CertificateParams::default();
    params
        .distinguished_name
        .push(DnType::CommonName, CA_COMMON_NAME);
    params.is_ca = IsCa::Ca(BasicConstraints::Unconstrained);
    params.key_usages = vec![
        KeyUsagePurpose::KeyCertSign,
        KeyUsagePurpose::DigitalSignature,
    ];
    params.not_before = validity.not_before;
    params.not_after = validity.not_after();
    params.serial_number = Some(SerialNumber::from(1u64));
    params
}

/// The CA as loaded from `dir`: its key, its certificate (parsed and as rcgen's issuer).
struct Ca {
    key: KeyPair,
    cert: Certificate,
    issuer: rcgen::Certificate,
}

fn load_ca(dir: &Path) -> Result<Ca, KeysError> {
    let key_path = dir.join(CA_KEY);
    let key = KeyPair::from_pem(&read(&key_path)?)
        .map_err(|e| fail(&key_path, format!("not a PEM private key: {e}")))?;
    let cert_path = dir.join(CA_CERT);
    let cert_der =
        pem::decode(&read(&cert_path)?, "CERTIFICATE").map_err(|e| fail(&cert_path, e))?;
    let cert = Certificate::from_der(&cert_der.0)
        .map_err(|e| fail(&cert_path, format!("not an X.509 certificate: {e}")))?;
    // rcgen signs with the issuer's name and key identifier, which come from its parameters
    // and key: the same parameters give the same issuer.
    let issuer = ca_params(Validity::from_now(1))
        .self_signed(&key)
        .map_err(|e| fail(&key_path, e))?;
    Ok(Ca { key, cert, issuer })
}

/// Signs `document` as the CA (S/MIME).
fn sign(ca: &Ca, document: &str, path: &Path) -> Result<String, KeysError> {
    smime::sign(document, &ca.key.serialize_der(), &ca.cert).map_err(|e| fail(path, e))
}

/// `rl keys init`: a new CA and the governance document in `dir` (created if missing). An
/// existing CA is never overwritten.
pub fn init(dir: &Path, dds: &Dds, validity: Validity) -> Result<Vec<PathBuf>, KeysError> {
    std::fs::create_dir_all(dir).map_err(|e| fail(dir, format!("cannot create: {e}")))?;
    let key_path = dir.join(CA_KEY);
    if key_path.exists() {
        return Err(fail(
            &key_path,
            "exists already: a CA is never overwritten (remove it to start over)",
        ));
    }
    let key = KeyPair::generate_for(&PKCS_ECDSA_P256_SHA256).map_err(|e| fail(&key_path, e))?;
    let cert = ca_params(validity)
        .self_signed(&key)
        .map_err(|e| fail(&key_path, e))?;
    write(&key_path, &key.serialize_pem(), true)?;
    write(&dir.join(CA_CERT), &cert.pem(), false)?;
    let ca = load_ca(dir)?;
    let mut written = vec![key_path, dir.join(CA_CERT)];
    let path = dir.join(GOVERNANCE);
    write(
        &path,
        &sign(&ca, &documents::governance(dds), &path)?,
        false,
    )?;
    written.push(path);
    Ok(written)
}

/// `rl keys add`: `grantee`'s keystore in a subdirectory of `dir`, which `init` made.
/// Returns the subdirectory.
pub fn add(
    dir: &Path,
    dds: &Dds,
    grantee: &Grantee,
    validity: Validity,
) -> Result<PathBuf, KeysError> {
    let ca = load_ca(dir)?;
    let target = dir.join(grantee.directory_name());
    std::fs::create_dir_all(&target).map_err(|e| fail(&target, format!("cannot create: {e}")))?;
    let key_path = target.join(KEY);
    let key = KeyPair::generate_for(&PKCS_ECDSA_P256_SHA256).map_err(|e| fail(&key_path, e))?;
    let mut params = CertificateParams::default();
    params
        .distinguished_name
        .push(DnType::CommonName, grantee.common_name());
    params.is_ca = IsCa::ExplicitNoCa;
    params.key_usages = vec![KeyUsagePurpose::DigitalSignature];
    params.not_before = validity.not_before;
    params.not_after = validity.not_after();
    let serial = (OffsetDateTime::now_utc()
        .unix_timestamp_nanos()
        .unsigned_abs() as u64)
        & 0x7fff_ffff_ffff_ffff;
    params.serial_number = Some(SerialNumber::from(serial));
    let cert_path = target.join(CERT);
    let cert = params
        .signed_by(&key, &ca.issuer, &ca.key)
        .map_err(|e| fail(&cert_path, e))?;
    write(&key_path, &key.serialize_pem(), true)?;
    write(&cert_path, &cert.pem(), false)?;
    let stamp = |t: OffsetDateTime| {
        format!(
            "{:04}-{:02}-{:02}T{:02}:{:02}:{:02}",
            t.year(),
            u8::from(t.month()),
            t.day(),
            t.hour(),
            t.minute(),
            t.second()
        )
    };
    let permissions_path = target.join(PERMISSIONS);
    let permissions = documents::permissions(
        dds,
        grantee,
        &stamp(validity.not_before),
        &stamp(validity.not_after()),
    );
    write(
        &permissions_path,
        &sign(&ca, &permissions, &permissions_path)?,
        false,
    )?;
    for shared in [CA_CERT, GOVERNANCE] {
        let from = dir.join(shared);
        write(&target.join(shared), &read(&from)?, false)?;
    }
    Ok(target)
}
