//! The one line an error prints: the message and each cause the text does not already hold.
//! Errors of the loaders name their source in their own message as well as chaining it (so
//! that a rejection logged alone still says why), which `{:#}` would print twice.

/// `error`'s chain joined with ": ", leaving out a cause whose text is already part of the
/// line.
pub fn error_line(error: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in error.chain() {
        let text = cause.to_string();
        if line.is_empty() {
            line = text;
        } else if !line.contains(&text) {
            line.push_str(": ");
            line.push_str(&text);
        }
    }
    line
}

#[cfg(test)]
mod tests {
    use super::*;

    /// As the loaders' `LoadError::Io`: the cause in the message and chained.
    #[derive(Debug)]
    struct ReadFailed {
        path: String,
        source: std::io::Error,
    }

    impl std::fmt::Display for ReadFailed {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            write!(f, "{}: cannot read: {}", self.path, self.source)
        }
    }

    impl std::error::Error for ReadFailed {
        fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
            Some(&self.source)
        }
    }

    #[test]
    fn a_cause_already_in_the_message_is_printed_once() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "no such file");
        let error = anyhow::Error::new(ReadFailed {
            path: "city.geojson".into(),
            source: io,
        })
        .context("cannot load the inputs");
        assert_eq!(
            error_line(&error),
            "cannot load the inputs: city.geojson: cannot read: no such file"
        );
        // A cause the message does not repeat is kept.
        let error = anyhow::anyhow!("disk full").context("writing scene.cwk");
        assert_eq!(error_line(&error), "writing scene.cwk: disk full");
    }
}
