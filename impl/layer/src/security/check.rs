//! The start-up check of a keystore: every file present, parsed, current, issued or signed by
//! the keystore's CA, and belonging together (the key is the certificate's, the permissions
//! name the certificate's subject). RustDDS checks the same when the participant is created,
//! but its errors do not say which file is at fault; these do.

use super::{pem, smime, Keystore, KeystoreError, CA_CERT, CERT, KEY, PERMISSIONS};
use x509_parser::certificate::X509Certificate;
use x509_parser::prelude::FromDer;

fn read(keystore: &Keystore, name: &str) -> Result<String, KeystoreError> {
    let path = keystore.path(name);
    std::fs::read_to_string(&path)
        .map_err(|e| KeystoreError::new(&path, format!("cannot read: {e}")))
}

fn certificate_der(keystore: &Keystore, name: &str) -> Result<pem::Der, KeystoreError> {
    let text = read(keystore, name)?;
    pem::decode(&text, "CERTIFICATE").map_err(|e| KeystoreError::new(&keystore.path(name), e))
}

fn parse<'a>(
    keystore: &Keystore,
    name: &str,
    der: &'a pem::Der,
) -> Result<X509Certificate<'a>, KeystoreError> {
    let (_, certificate) = X509Certificate::from_der(&der.0).map_err(|e| {
        KeystoreError::new(
            &keystore.path(name),
            format!("not an X.509 certificate: {e}"),
        )
    })?;
    let validity = certificate.validity();
    if !validity.is_valid() {
        let now = x509_parser::time::ASN1Time::now();
        let problem = if now < validity.not_before {
            format!("not valid before {}", validity.not_before)
        } else {
            format!("expired on {}", validity.not_after)
        };
        return Err(KeystoreError::new(&keystore.path(name), problem));
    }
    Ok(certificate)
}

/// Checks every file of `keystore`; the first problem found is the error.
pub fn check(keystore: &Keystore) -> Result<(), KeystoreError> {
    let ca_der = certificate_der(keystore, CA_CERT)?;
    let ca = parse(keystore, CA_CERT, &ca_der)?;
    let ca_key = ca.public_key().subject_public_key.data.to_vec();

    let cert_der = certificate_der(keystore, CERT)?;
    let cert = parse(keystore, CERT, &cert_der)?;
    cert.verify_signature(Some(ca.public_key())).map_err(|_| {
        KeystoreError::new(
            &keystore.path(CERT),
            format!(
                "was not issued by the CA of {}",
                keystore.path(CA_CERT).display()
            ),
        )
    })?;

    let key_text = read(keystore, KEY)?;
    let key_der = pem::decode(&key_text, "PRIVATE KEY")
        .map_err(|e| KeystoreError::new(&keystore.path(KEY), e))?;
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
    if ring::signature::KeyPair::public_key(&key).as_ref()
        != cert.public_key().subject_public_key.data.as_ref()
    {
        return Err(KeystoreError::new(
            &keystore.path(KEY),
            format!("is not the key of {}", keystore.path(CERT).display()),
        ));
    }

    let governance = super::GOVERNANCE;
    smime::verify(&read(keystore, governance)?, &ca_key)
        .map_err(|e| KeystoreError::new(&keystore.path(governance), e))?;

    let permissions = smime::verify(&read(keystore, PERMISSIONS)?, &ca_key)
        .map_err(|e| KeystoreError::new(&keystore.path(PERMISSIONS), e))?;
    let subject = cert.subject().to_string();
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
