//! Where the bundles live (`--store`): a directory, or a bucket of an S3-compatible object store.

use std::path::PathBuf;

#[derive(Clone, Debug, PartialEq)]
pub enum Location {
    /// A data directory: `file:///path`, or a plain path.
    Dir(PathBuf),
    /// `s3://bucket/prefix`: the bundles are objects `prefix/<id>.vtex` of `bucket`.
    S3 { bucket: String, prefix: String },
}

impl std::str::FromStr for Location {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let s = s.trim();
        if let Some(rest) = s.strip_prefix("s3://") {
            let (bucket, prefix) = rest.split_once('/').unwrap_or((rest, ""));
            // The S3 bucket naming rules: 3 to 63 lower-case letters, digits, dots and hyphens.
            let valid = (3..=63).contains(&bucket.len())
                && bucket.bytes().all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'.' || b == b'-');
            if !valid {
                return Err(format!(
                    "`{s}`: the bucket name must be 3 to 63 lower-case letters, digits, dots or hyphens"
                ));
            }
            let prefix = prefix.trim_matches('/');
            if prefix.split('/').any(|part| part.is_empty() || part == "." || part == "..") && !prefix.is_empty() {
                return Err(format!("`{s}`: the prefix has an empty, `.` or `..` part"));
            }
            return Ok(Location::S3 { bucket: bucket.to_string(), prefix: prefix.to_string() });
        }
        if let Some(path) = s.strip_prefix("file://") {
            if !path.starts_with('/') {
                return Err(format!("`{s}`: a file URL names an absolute path, file:///path"));
            }
            return Ok(Location::Dir(PathBuf::from(path)));
        }
        if let Some((scheme, _)) = s.split_once("://") {
            return Err(format!("`{scheme}://` is not a store vtex knows: s3://bucket/prefix, file:///path or a path"));
        }
        if s.is_empty() {
            return Err("the store location is empty".into());
        }
        Ok(Location::Dir(PathBuf::from(s)))
    }
}

impl std::fmt::Display for Location {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Location::Dir(dir) => write!(f, "{}", dir.display()),
            Location::S3 { bucket, prefix } if prefix.is_empty() => write!(f, "s3://{bucket}"),
            Location::S3 { bucket, prefix } => write!(f, "s3://{bucket}/{prefix}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn locations_parse_as_documented() {
        let parse = |s: &str| s.parse::<Location>();
        assert_eq!(
            parse("s3://vtex/encodings/").unwrap(),
            Location::S3 { bucket: "vtex".into(), prefix: "encodings".into() }
        );
        assert_eq!(parse("s3://vtex").unwrap(), Location::S3 { bucket: "vtex".into(), prefix: String::new() });
        assert_eq!(parse("s3://vtex/a/b").unwrap().to_string(), "s3://vtex/a/b");
        assert_eq!(parse("file:///var/lib/vtex").unwrap(), Location::Dir("/var/lib/vtex".into()));
        assert_eq!(parse("./vtex-data").unwrap(), Location::Dir("./vtex-data".into()));
        for bad in ["s3://", "s3://Upper", "s3://vtex/a//b", "s3://vtex/../x", "file://relative", "gs://b/p", ""] {
            assert!(parse(bad).is_err(), "{bad} was accepted");
        }
    }
}
