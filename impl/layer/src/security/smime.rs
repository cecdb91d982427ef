//! Signed documents as DDS Security wants them: S/MIME `multipart/signed` with a detached
//! CMS SignedData (RFC 5652) signature, ECDSA P-256 with SHA-256, the signer's certificate
//! included. The layout is what `openssl smime -sign -text` writes, which is what RustDDS
//! and other DDS implementations read: the signed content is the first MIME part (its
//! `Content-Type: text/plain` header included) with CRLF line ends.
//!
//! [`sign`] writes one (`rl keys`); [`verify`] checks one against the CA certificate and
//! returns the document, so a keystore is checked before DDS reads it.

use super::pem::{der_length, Der};
use base64::Engine;
use ring::{digest, rand::SystemRandom, signature};
use x509_parser::der_parser::asn1_rs::{Any, FromDer};

const OID_SIGNED_DATA: &[u64] = &[1, 2, 840, 113549, 1, 7, 2];
const OID_DATA: &[u64] = &[1, 2, 840, 113549, 1, 7, 1];
const OID_SHA256: &[u64] = &[2, 16, 840, 1, 101, 3, 4, 2, 1];
const OID_ECDSA_SHA256: &[u64] = &[1, 2, 840, 10045, 4, 3, 2];
const OID_CONTENT_TYPE: &[u64] = &[1, 2, 840, 113549, 1, 9, 3];
const OID_MESSAGE_DIGEST: &[u64] = &[1, 2, 840, 113549, 1, 9, 4];
const BOUNDARY: &str = "----RL-DDS-SECURITY-SIGNED-DOCUMENT";

/// What the first MIME part holds: the header and the document, CRLF line ends. This is what
/// the signature covers.
fn signed_content(document: &str) -> Vec<u8> {
    let text = format!("Content-Type: text/plain\n\n{document}");
    text.replace("\r\n", "\n")
        .replace('\n', "\r\n")
        .into_bytes()
}

/// Signs `document` with the CA's PKCS#8 key; `signer_cert` (DER) goes into the signature.
/// `issuer_der` and `serial_der` are the signer certificate's issuer name and serial number,
/// both DER, which identify the signer.
pub fn sign(
    document: &str,
    signer_key_pkcs8: &[u8],
    signer_cert: &Der,
    issuer_der: &[u8],
    serial_der: &[u8],
) -> Result<String, String> {
    let rng = SystemRandom::new();
    let key = signature::EcdsaKeyPair::from_pkcs8(
        &signature::ECDSA_P256_SHA256_ASN1_SIGNING,
        signer_key_pkcs8,
        &rng,
    )
    .map_err(|e| format!("the CA key is not an ECDSA P-256 PKCS#8 key: {e}"))?;
    let document = document.trim_end();
    let content = signed_content(document);
    let content_digest = digest::digest(&digest::SHA256, &content);
    let attributes = yasna::construct_der(|w| {
        w.write_set_of(|w| {
            w.next().write_sequence(|w| {
                w.next()
                    .write_oid(&yasna::models::ObjectIdentifier::from_slice(
                        OID_CONTENT_TYPE,
                    ));
                w.next().write_set(|w| {
                    w.next()
                        .write_oid(&yasna::models::ObjectIdentifier::from_slice(OID_DATA))
                });
            });
            w.next().write_sequence(|w| {
                w.next()
                    .write_oid(&yasna::models::ObjectIdentifier::from_slice(
                        OID_MESSAGE_DIGEST,
                    ));
                w.next()
                    .write_set(|w| w.next().write_bytes(content_digest.as_ref()));
            });
        })
    });
    let attribute_signature = key
        .sign(&rng, &attributes)
        .map_err(|e| format!("cannot sign: {e}"))?;
    // In the SignerInfo the same SET goes as [0] IMPLICIT: only the tag byte differs.
    let mut implicit_attributes = attributes.clone();
    implicit_attributes[0] = 0xA0;
    let oid = |arcs: &[u64]| yasna::models::ObjectIdentifier::from_slice(arcs);
    let content_info = yasna::construct_der(|w| {
        w.write_sequence(|w| {
            w.next().write_oid(&oid(OID_SIGNED_DATA));
            w.next().write_tagged(yasna::Tag::context(0), |w| {
                w.write_sequence(|w| {
                    w.next().write_u8(1);
                    w.next().write_set(|w| {
                        w.next()
                            .write_sequence(|w| w.next().write_oid(&oid(OID_SHA256)))
                    });
                    w.next()
                        .write_sequence(|w| w.next().write_oid(&oid(OID_DATA)));
                    w.next().write_tagged_implicit(yasna::Tag::context(0), |w| {
                        w.write_set(|w| w.next().write_der(&signer_cert.0))
                    });
                    w.next().write_set(|w| {
                        w.next().write_sequence(|w| {
                            w.next().write_u8(1);
                            w.next().write_sequence(|w| {
                                w.next().write_der(issuer_der);
                                w.next().write_der(serial_der);
                            });
                            w.next()
                                .write_sequence(|w| w.next().write_oid(&oid(OID_SHA256)));
                            w.next().write_der(&implicit_attributes);
                            w.next()
                                .write_sequence(|w| w.next().write_oid(&oid(OID_ECDSA_SHA256)));
                            w.next().write_bytes(attribute_signature.as_ref());
                        })
                    });
                })
            });
        })
    });
    let encoded = base64::engine::general_purpose::STANDARD.encode(content_info);
    let mut signature_lines = String::new();
    for chunk in encoded.as_bytes().chunks(64) {
        signature_lines.push_str(&String::from_utf8_lossy(chunk));
        signature_lines.push('\n');
    }
    Ok(format!(
        "MIME-Version: 1.0\n\
         Content-Type: multipart/signed; protocol=\"application/x-pkcs7-signature\"; micalg=\"sha-256\"; boundary=\"{BOUNDARY}\"\n\
         \n\
         This is an S/MIME signed message\n\
         \n\
         --{BOUNDARY}\n\
         Content-Type: text/plain\n\
         \n\
         {document}\n\
         --{BOUNDARY}\n\
         Content-Type: application/x-pkcs7-signature; name=\"smime.p7s\"\n\
         Content-Transfer-Encoding: base64\n\
         Content-Disposition: attachment; filename=\"smime.p7s\"\n\
         \n\
         {signature_lines}\n\
         --{BOUNDARY}--\n"
    ))
}

/// The parts of a signed document: the document, and the DER signature.
struct Parts {
    document: String,
    signature: Vec<u8>,
}

fn split(text: &str) -> Result<Parts, String> {
    let text = text.replace("\r\n", "\n");
    let boundary = text
        .lines()
        .find_map(|line| {
            let (_, rest) = line.split_once("boundary=\"")?;
            rest.split_once('"').map(|(b, _)| b.to_string())
        })
        .ok_or("not an S/MIME signed document (no multipart boundary)")?;
    let delimiter = format!("\n--{boundary}");
    let mut parts = text.split(&delimiter).skip(1);
    let (Some(content), Some(signature)) = (parts.next(), parts.next()) else {
        return Err("not an S/MIME signed document (expected two parts)".into());
    };
    let body = |part: &str| {
        part.split_once("\n\n")
            .map(|(_, body)| body.trim_start_matches('\n').to_string())
    };
    let document = body(content).ok_or("the signed part has no body")?;
    let signature_base64: String = body(signature)
        .ok_or("the signature part has no body")?
        .chars()
        .filter(|c| !c.is_whitespace())
        .collect();
    let signature = base64::engine::general_purpose::STANDARD
        .decode(signature_base64)
        .map_err(|e| format!("the signature is not base64: {e}"))?;
    Ok(Parts {
        document,
        signature,
    })
}

/// The elements of a DER SEQUENCE or SET (the content of `outer`).
fn elements<'a>(outer: &Any<'a>) -> Result<Vec<Any<'a>>, String> {
    let mut rest = outer.data;
    let mut items = Vec::new();
    while !rest.is_empty() {
        let (next, item) = Any::from_der(rest).map_err(|e| format!("bad DER: {e}"))?;
        items.push(item);
        rest = next;
    }
    Ok(items)
}

fn nth<'a>(items: &[Any<'a>], index: usize, what: &str) -> Result<Any<'a>, String> {
    items
        .get(index)
        .cloned()
        .ok_or_else(|| format!("the signature lacks its {what}"))
}

/// Checks that `text` is a document signed with the key of `ca_public_key` (the CA
/// certificate's uncompressed EC point) and returns the document.
pub fn verify(text: &str, ca_public_key: &[u8]) -> Result<String, String> {
    let parts = split(text)?;
    let (_, content_info) =
        Any::from_der(&parts.signature).map_err(|e| format!("bad signature DER: {e}"))?;
    let content_info = elements(&content_info)?;
    let explicit = nth(&content_info, 1, "SignedData")?;
    let (_, signed_data) =
        Any::from_der(explicit.data).map_err(|e| format!("bad SignedData: {e}"))?;
    let signed_data = elements(&signed_data)?;
    let signer_infos = signed_data
        .last()
        .ok_or("the signature has no signer")?
        .clone();
    let signer = nth(&elements(&signer_infos)?, 0, "signer")?;
    let signer = elements(&signer)?;
    // version, sid, digestAlgorithm, [0] signedAttrs, signatureAlgorithm, signature
    let attributes = nth(&signer, 3, "signed attributes")?;
    let signature_value = nth(&signer, 5, "signature value")?;
    let mut attributes_der = vec![0x31];
    attributes_der.extend(der_length(attributes.data.len()));
    attributes_der.extend_from_slice(attributes.data);
    signature::UnparsedPublicKey::new(&signature::ECDSA_P256_SHA256_ASN1, ca_public_key)
        .verify(&attributes_der, signature_value.data)
        .map_err(|_| "its signature is not the CA's (signed by another CA, or altered)")?;
    let content_digest = digest::digest(&digest::SHA256, &signed_content(&parts.document));
    let digest_matches = elements(&attributes)?.iter().any(|attribute| {
        elements(attribute).is_ok_and(|a| {
            a.len() == 2
                && elements(&a[1])
                    .is_ok_and(|values| values.iter().any(|v| v.data == content_digest.as_ref()))
        })
    });
    if !digest_matches {
        return Err("the document was altered after it was signed".into());
    }
    Ok(parts.document)
}

#[cfg(test)]
mod tests {
    use super::{sign, verify};
    use crate::security::pem::Der;
    use rcgen::{CertificateParams, KeyPair, PKCS_ECDSA_P256_SHA256};
    use x509_parser::prelude::FromDer;

    /// A signer: its PKCS#8 key, certificate, issuer name and serial (DER), public key.
    fn signer() -> (Vec<u8>, Der, Vec<u8>, Vec<u8>, Vec<u8>) {
        let key = KeyPair::generate_for(&PKCS_ECDSA_P256_SHA256).unwrap();
        let mut params = CertificateParams::default();
        params.serial_number = Some(rcgen::SerialNumber::from(7u64));
        let cert = params.self_signed(&key).unwrap();
        let der = cert.der().to_vec();
        let (_, parsed) = x509_parser::certificate::X509Certificate::from_der(&der).unwrap();
        let issuer = parsed.tbs_certificate.issuer.as_raw().to_vec();
        let serial = vec![0x02, 0x01, 0x07];
        let public = parsed.public_key().subject_public_key.data.to_vec();
        (key.serialize_der(), Der(der), issuer, serial, public)
    }

    #[test]
    fn a_signed_document_verifies_and_an_altered_or_foreign_one_does_not() {
        let (key, cert, issuer, serial, public) = signer();
        let document = "<dds>\n  <x>1</x>\n</dds>\n";
        let signed = sign(document, &key, &cert, &issuer, &serial).unwrap();
        assert_eq!(verify(&signed, &public).unwrap(), document.trim_end());
        let altered = signed.replace("<x>1</x>", "<x>2</x>");
        assert!(verify(&altered, &public).unwrap_err().contains("altered"));
        let (_, _, _, _, other_public) = signer();
        assert!(verify(&signed, &other_public)
            .unwrap_err()
            .contains("not the CA's"));
        // CRLF line ends (a file edited on another system) verify the same.
        assert!(verify(&signed.replace('\n', "\r\n"), &public).is_ok());
    }
}
