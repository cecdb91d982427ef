//! Signed documents as DDS Security wants them: S/MIME `multipart/signed` with a detached
//! CMS SignedData (RFC 5652) signature, ECDSA P-256 with SHA-256, the signer's certificate
//! included. The layout is what `openssl smime -sign -text` writes, which is what RustDDS
//! and other DDS implementations read: the signed content is the first MIME part (its
//! `Content-Type: text/plain` header included) with CRLF line ends.
//!
//! [`sign`] writes one (`rl keys`); [`verify`] checks one against the CA certificate and
//! returns the document, so a keystore is checked before DDS reads it.

use super::certificate::{self, Certificate};
use base64::Engine;
use cms::cert::{CertificateChoices, IssuerAndSerialNumber};
use cms::content_info::{CmsVersion, ContentInfo};
use cms::signed_data::{
    CertificateSet, EncapsulatedContentInfo, SignedAttributes, SignedData, SignerIdentifier,
    SignerInfo, SignerInfos,
};
use der::asn1::{ObjectIdentifier, OctetString, SetOfVec};
use der::{Any, Decode, Encode};
use ring::{digest, rand::SystemRandom, signature};
use spki::AlgorithmIdentifierOwned;
use x509_cert::attr::Attribute;

const ID_SIGNED_DATA: ObjectIdentifier = ObjectIdentifier::new_unwrap("1.2.840.113549.1.7.2");
const ID_DATA: ObjectIdentifier = ObjectIdentifier::new_unwrap("1.2.840.113549.1.7.1");
const ID_SHA_256: ObjectIdentifier = ObjectIdentifier::new_unwrap("2.16.840.1.101.3.4.2.1");
const ID_CONTENT_TYPE: ObjectIdentifier = ObjectIdentifier::new_unwrap("1.2.840.113549.1.9.3");
const ID_MESSAGE_DIGEST: ObjectIdentifier = ObjectIdentifier::new_unwrap("1.2.840.113549.1.9.4");
const BOUNDARY: &str = "----RL-DDS-SECURITY-SIGNED-DOCUMENT";

/// Why a document could not be signed, or is not a valid signed document.
#[derive(Debug, thiserror::Error)]
pub enum SmimeError {
    /// The signing key is not what DDS Security's builtin plugins use.
    #[error("the CA key is not an ECDSA P-256 PKCS#8 key: {0}")]
    Key(ring::error::KeyRejected),
    /// The system's random source failed while signing.
    #[error("cannot sign: the random source failed")]
    Random,
    /// The MIME layout is not `multipart/signed` with two parts.
    #[error("not an S/MIME signed document ({0})")]
    Layout(&'static str),
    /// The signature part is not base64.
    #[error("the signature is not base64: {0}")]
    Base64(#[from] base64::DecodeError),
    /// The signature does not decode as a CMS SignedData, or a structure could not be encoded.
    #[error("the signature is not a CMS SignedData: {0}")]
    Der(#[from] der::Error),
    /// A part the signature must have is absent.
    #[error("the signature lacks its {0}")]
    Lacks(&'static str),
    /// The signature uses an algorithm other than ECDSA with SHA-256.
    #[error("the signature uses {0}, not ECDSA with SHA-256")]
    Algorithm(ObjectIdentifier),
    /// The signature was not made with the CA's key.
    #[error("its signature is not the CA's (signed by another CA, or altered)")]
    NotTheCas,
    /// The signed digest is not the document's.
    #[error("the document was altered after it was signed")]
    Altered,
}

/// What the first MIME part holds: the header and the document, CRLF line ends. This is what
/// the signature covers.
fn signed_content(document: &str) -> Vec<u8> {
    let text = format!("Content-Type: text/plain\n\n{document}");
    text.replace("\r\n", "\n")
        .replace('\n', "\r\n")
        .into_bytes()
}

fn algorithm(oid: ObjectIdentifier) -> AlgorithmIdentifierOwned {
    AlgorithmIdentifierOwned {
        oid,
        parameters: None,
    }
}

fn attribute(oid: ObjectIdentifier, value: Any) -> Result<Attribute, SmimeError> {
    Ok(Attribute {
        oid,
        values: SetOfVec::try_from(vec![value])?,
    })
}

/// The signed attributes: the content type (data) and the SHA-256 digest of `content`.
fn signed_attributes(content: &[u8]) -> Result<SignedAttributes, SmimeError> {
    let content_digest = digest::digest(&digest::SHA256, content);
    let digest = OctetString::new(content_digest.as_ref())?;
    Ok(SetOfVec::try_from(vec![
        attribute(ID_CONTENT_TYPE, Any::encode_from(&ID_DATA)?)?,
        attribute(ID_MESSAGE_DIGEST, Any::encode_from(&digest)?)?,
    ])?)
}

/// Signs `document` with the CA's PKCS#8 key; the CA's certificate `signer` goes into the
/// signature and names the signer (its issuer and serial number).
pub fn sign(
    document: &str,
    signer_key_pkcs8: &[u8],
    signer: &Certificate,
) -> Result<String, SmimeError> {
    let rng = SystemRandom::new();
    let key = signature::EcdsaKeyPair::from_pkcs8(
        &signature::ECDSA_P256_SHA256_ASN1_SIGNING,
        signer_key_pkcs8,
        &rng,
    )
    .map_err(SmimeError::Key)?;
    let document = document.trim_end();
    let attributes = signed_attributes(&signed_content(document))?;
    // The signature covers the attributes' DER as a SET (RFC 5652, 5.4), not as the
    // [0] IMPLICIT field they are in the SignerInfo.
    let attribute_signature = key
        .sign(&rng, &attributes.to_der()?)
        .map_err(|_| SmimeError::Random)?;
    let tbs = signer.tbs_certificate();
    let signer_info = SignerInfo {
        version: CmsVersion::V1,
        sid: SignerIdentifier::IssuerAndSerialNumber(IssuerAndSerialNumber {
            issuer: tbs.issuer().clone(),
            serial_number: tbs.serial_number().clone(),
        }),
        digest_alg: algorithm(ID_SHA_256),
        signed_attrs: Some(attributes),
        signature_algorithm: algorithm(certificate::ECDSA_WITH_SHA_256),
        signature: OctetString::new(attribute_signature.as_ref())?,
        unsigned_attrs: None,
    };
    let signed_data = SignedData {
        version: CmsVersion::V1,
        digest_algorithms: SetOfVec::try_from(vec![algorithm(ID_SHA_256)])?,
        encap_content_info: EncapsulatedContentInfo {
            econtent_type: ID_DATA,
            econtent: None,
        },
        certificates: Some(CertificateSet(SetOfVec::try_from(vec![
            CertificateChoices::Certificate(signer.clone()),
        ])?)),
        crls: None,
        signer_infos: SignerInfos(SetOfVec::try_from(vec![signer_info])?),
    };
    let content_info = ContentInfo {
        content_type: ID_SIGNED_DATA,
        content: Any::encode_from(&signed_data)?,
    };
    let encoded = base64::engine::general_purpose::STANDARD.encode(content_info.to_der()?);
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

fn split(text: &str) -> Result<Parts, SmimeError> {
    let text = text.replace("\r\n", "\n");
    let boundary = text
        .lines()
        .find_map(|line| {
            let (_, rest) = line.split_once("boundary=\"")?;
            rest.split_once('"').map(|(b, _)| b.to_string())
        })
        .ok_or(SmimeError::Layout("no multipart boundary"))?;
    let delimiter = format!("\n--{boundary}");
    let mut parts = text.split(&delimiter).skip(1);
    let (Some(content), Some(signature)) = (parts.next(), parts.next()) else {
        return Err(SmimeError::Layout("expected two parts"));
    };
    let body = |part: &str| {
        part.split_once("\n\n")
            .map(|(_, body)| body.trim_start_matches('\n').to_string())
    };
    let document = body(content).ok_or(SmimeError::Layout("the signed part has no body"))?;
    let signature_base64: String = body(signature)
        .ok_or(SmimeError::Layout("the signature part has no body"))?
        .chars()
        .filter(|c| !c.is_whitespace())
        .collect();
    let signature = base64::engine::general_purpose::STANDARD.decode(signature_base64)?;
    Ok(Parts {
        document,
        signature,
    })
}

/// The one signer of a CMS `ContentInfo` holding a SignedData.
fn signer_info(signature_der: &[u8]) -> Result<SignerInfo, SmimeError> {
    let content_info = ContentInfo::from_der(signature_der)?;
    if content_info.content_type != ID_SIGNED_DATA {
        return Err(SmimeError::Lacks("SignedData"));
    }
    let signed_data: SignedData = content_info.content.decode_as()?;
    signed_data
        .signer_infos
        .0
        .into_vec()
        .into_iter()
        .next()
        .ok_or(SmimeError::Lacks("signer"))
}

/// Checks that `text` is a document signed with the key of `ca_public_key` (the CA
/// certificate's uncompressed EC point) and returns the document.
pub fn verify(text: &str, ca_public_key: &[u8]) -> Result<String, SmimeError> {
    let parts = split(text)?;
    let signer = signer_info(&parts.signature)?;
    if signer.signature_algorithm.oid != certificate::ECDSA_WITH_SHA_256 {
        return Err(SmimeError::Algorithm(signer.signature_algorithm.oid));
    }
    let attributes = signer
        .signed_attrs
        .ok_or(SmimeError::Lacks("signed attributes"))?;
    signature::UnparsedPublicKey::new(&signature::ECDSA_P256_SHA256_ASN1, ca_public_key)
        .verify(&attributes.to_der()?, signer.signature.as_bytes())
        .map_err(|_| SmimeError::NotTheCas)?;
    let content_digest = digest::digest(&digest::SHA256, &signed_content(&parts.document));
    let signed_digest = attributes
        .iter()
        .find(|attribute| attribute.oid == ID_MESSAGE_DIGEST)
        .and_then(|attribute| attribute.values.iter().next())
        .ok_or(SmimeError::Lacks("message digest"))?
        .decode_as::<OctetString>()?;
    if signed_digest.as_bytes() != content_digest.as_ref() {
        return Err(SmimeError::Altered);
    }
    Ok(parts.document)
}

#[cfg(test)]
mod tests {
    use super::{sign, verify, SmimeError};
    use crate::security::certificate::Certificate;
    use der::Decode;
    use rcgen::{CertificateParams, KeyPair, PKCS_ECDSA_P256_SHA256};

    /// A signer: its PKCS#8 key, its certificate, its public key.
    fn signer() -> (Vec<u8>, Certificate, Vec<u8>) {
        let key = KeyPair::generate_for(&PKCS_ECDSA_P256_SHA256).unwrap();
        let mut params = CertificateParams::default();
        params.serial_number = Some(rcgen::SerialNumber::from(7u64));
        let cert = params.self_signed(&key).unwrap();
        let cert = Certificate::from_der(cert.der()).unwrap();
        let public = crate::security::certificate::public_key(&cert).to_vec();
        (key.serialize_der(), cert, public)
    }

    #[test]
    fn a_signed_document_verifies_and_an_altered_or_foreign_one_does_not() {
        let (key, cert, public) = signer();
        let document = "<dds>\n  <x>1</x>\n</dds>\n";
        let signed = sign(document, &key, &cert).unwrap();
        assert_eq!(verify(&signed, &public).unwrap(), document.trim_end());
        let altered = signed.replace("<x>1</x>", "<x>2</x>");
        assert!(matches!(
            verify(&altered, &public),
            Err(SmimeError::Altered)
        ));
        let (_, _, other_public) = signer();
        assert!(matches!(
            verify(&signed, &other_public),
            Err(SmimeError::NotTheCas)
        ));
        // CRLF line ends (a file edited on another system) verify the same.
        assert!(verify(&signed.replace('\n', "\r\n"), &public).is_ok());
    }

    #[test]
    fn a_damaged_signature_is_named_not_a_panic() {
        let (key, cert, public) = signer();
        let signed = sign("<dds/>", &key, &cert).unwrap();
        let truncated = signed.replace("smime.p7s\"\n\nM", "smime.p7s\"\n\nMIIB");
        assert!(verify(&truncated, &public).is_err());
        assert!(matches!(
            verify("<dds/>", &public),
            Err(SmimeError::Layout(_))
        ));
    }
}
