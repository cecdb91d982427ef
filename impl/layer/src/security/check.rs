//! The start-up check of a keystore: every file present, parsed, current, issued or signed by
//! the keystore's CA, and belonging together (the key is the certificate's, the permissions
//! name the certificate's subject). RustDDS checks the same when the participant is created,
//! but its errors do not say which file is at fault; these do.

use super::certificate::{self, Certificate};
use super::{pem, smime, Keystore, KeystoreError, CA_CERT, CERT, KEY, PERMISSIONS};
use der::Decode;

fn read(keystore: &Keystore, name: &str) -> Result<String, KeystoreError> {
    let path = keystore.path(name);
    std::fs::read_to_string(&path)
        .map_err(|e| KeystoreError::new(&path, format!("cannot read: {e}")))
}

/// The certificate in the keystore's file `name`, parsed and current.
fn certificate(keystore: &Keystore, name: &str) -> Result<Certificate, KeystoreError> {
    let path = keystore.path(name);
    let der = pem::decode(&read(keystore, name)?, "CERTIFICATE")
        .map_err(|e| KeystoreError::new(&path, e.to_string()))?;
    let certificate = Certificate::from_der(&der.0)
        .map_err(|e| KeystoreError::new(&path, format!("not an X.509 certificate: {e}")))?;
    certificate::current(&certificate, std::time::SystemTime::now())
        .map_err(|e| KeystoreError::new(&path, e.to_string()))?;
    Ok(certificate)
}

/// Checks every file of `keystore`; the first problem found is the error.
pub fn check(keystore: &Keystore) -> Result<(), KeystoreError> {
    let ca = certificate(keystore, CA_CERT)?;
    let ca_key = certificate::public_key(&ca);

    let cert = certificate(keystore, CERT)?;
    if !certificate::issued_by(&cert, &ca) {
        return Err(KeystoreError::new(
            &keystore.path(CERT),
            format!(
                "was not issued by the CA of {}",
                keystore.path(CA_CERT).display()
            ),
        ));
    }

    let key_text = read(keystore, KEY)?;
    let key_der = pem::decode(&key_text, "PRIVATE KEY")
        .map_err(|e| KeystoreError::new(&keystore.path(KEY), e.to_string()))?;
    let key = ring::signature::EcdsaKeyPair::from_pkcs8(
        &ring::signature::ECDSA_P256_SHA256_ASN1_SIGNING,
        &key_der.0,
        &ring::rand::SystemRandom::new(),
    )
    .map_err(|e| {
        KeystoreError::new(
            &keystore.path(KEY),
            format!("not an ECDSA P-256 PKCS#8 key: {e}"),
        )
    })?;
    if ring::signature::KeyPair::public_key(&key).as_ref() != certificate::public_key(&cert) {
        return Err(KeystoreError::new(
            &keystore.path(KEY),
            format!("is not the key of {}", keystore.path(CERT).display()),
        ));
    }

    let governance = super::GOVERNANCE;
    smime::verify(&read(keystore, governance)?, ca_key)
        .map_err(|e| KeystoreError::new(&keystore.path(governance), e.to_string()))?;

    let permissions = smime::verify(&read(keystore, PERMISSIONS)?, ca_key)
        .map_err(|e| KeystoreError::new(&keystore.path(PERMISSIONS), e.to_string()))?;
    let subject = cert.tbs_certificate().subject().to_string();
    match super::documents::permissions_subject(&permissions) {
        Some(granted) if granted == subject => Ok(()),
        granted => Err(KeystoreError::new(
            &keystore.path(PERMISSIONS),
            format!(
                "grants {}, not the subject of {} ({subject})",
                granted.unwrap_or("no subject"),
                keystore.path(CERT).display()
            ),
        )),
    }
}
