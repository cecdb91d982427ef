//! Small DER and PEM helpers shared by the signer and the keystore checks.

/// DER bytes (a certificate, a name, a key).
#[derive(Clone, Debug)]
pub struct Der(pub Vec<u8>);

/// The DER length octets for a content of `length` bytes.
pub fn der_length(length: usize) -> Vec<u8> {
    if length < 0x80 {
        return vec![length as u8];
    }
    let bytes: Vec<u8> = length
        .to_be_bytes()
        .into_iter()
        .skip_while(|b| *b == 0)
        .collect();
    let mut out = vec![0x80 | bytes.len() as u8];
    out.extend(bytes);
    out
}

/// The first PEM block labelled `label` in `text`, decoded.
pub fn decode(text: &str, label: &str) -> Result<Der, String> {
    let mut rest = text.as_bytes();
    loop {
        match x509_parser::pem::Pem::read(std::io::Cursor::new(rest)) {
            Ok((pem, consumed)) => {
                if pem.label == label {
                    return Ok(Der(pem.contents));
                }
                rest = &rest[consumed..];
            }
            Err(_) => return Err(format!("no PEM block \"{label}\"")),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::der_length;

    #[test]
    fn der_lengths() {
        assert_eq!(der_length(5), [5]);
        assert_eq!(der_length(0x80), [0x81, 0x80]);
        assert_eq!(der_length(0x1234), [0x82, 0x12, 0x34]);
    }
}
