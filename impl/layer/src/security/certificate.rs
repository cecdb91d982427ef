//! X.509 certificates of a keystore, read with RustCrypto's `x509-cert` (the ASN.1 stack
//! RustDDS's security code links too): the key a certificate holds, whether the CA issued it,
//! and whether it is current.

use der::asn1::ObjectIdentifier;
use der::Encode;
use std::time::SystemTime;

pub use x509_cert::Certificate;

/// ECDSA with SHA-256 (RFC 5758): the one signature algorithm of RL's keystores, as of DDS
/// Security's builtin plugins with P-256 keys.
pub const ECDSA_WITH_SHA_256: ObjectIdentifier =
    ObjectIdentifier::new_unwrap("1.2.840.10045.4.3.2");

/// The certificate's public key: for P-256, the uncompressed EC point.
pub fn public_key(certificate: &Certificate) -> &[u8] {
    certificate
        .tbs_certificate()
        .subject_public_key_info()
        .subject_public_key
        .raw_bytes()
}

/// Whether `certificate` carries a valid ECDSA P-256 SHA-256 signature by `issuer`'s key.
pub fn issued_by(certificate: &Certificate, issuer: &Certificate) -> bool {
    if certificate.signature_algorithm().oid != ECDSA_WITH_SHA_256 {
        return false;
    }
    let Ok(tbs) = certificate.tbs_certificate().to_der() else {
        return false;
    };
    let Some(signature) = certificate.signature().as_bytes() else {
        return false;
    };
    ring::signature::UnparsedPublicKey::new(
        &ring::signature::ECDSA_P256_SHA256_ASN1,
        public_key(issuer),
    )
    .verify(&tbs, signature)
    .is_ok()
}

/// Why a certificate is not current.
#[derive(Debug, thiserror::Error)]
pub enum NotCurrent {
    /// Its validity starts later.
    #[error("not valid before {0}")]
    NotYet(x509_cert::time::Time),
    /// Its validity ended.
    #[error("expired on {0}")]
    Expired(x509_cert::time::Time),
}

/// Whether `certificate` is valid at `now`.
pub fn current(certificate: &Certificate, now: SystemTime) -> Result<(), NotCurrent> {
    let validity = certificate.tbs_certificate().validity();
    if now < validity.not_before.to_system_time() {
        return Err(NotCurrent::NotYet(validity.not_before));
    }
    if now > validity.not_after.to_system_time() {
        return Err(NotCurrent::Expired(validity.not_after));
    }
    Ok(())
}
