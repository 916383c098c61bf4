//! The page's files, compiled into the binary: nothing is read from disk or fetched
//! at run time. three.js is vendored from npm with its licence
//! (`assets/view/vendor/three/`).

macro_rules! asset {
    ($path:literal, $mime:literal) => {
        ($path, include_str!(concat!("../../../assets/view/", $path)), $mime)
    };
}

/// (path, content, MIME type) of every served file.
const ASSETS: &[(&str, &str, &str)] = &[
    asset!("index.html", "text/html; charset=utf-8"),
    asset!("app.js", "text/javascript; charset=utf-8"),
    asset!("vendor/three/three.module.js", "text/javascript; charset=utf-8"),
    asset!("vendor/three/three.core.js", "text/javascript; charset=utf-8"),
    asset!("vendor/three/OrbitControls.js", "text/javascript; charset=utf-8"),
    asset!("vendor/three/LICENSE", "text/plain; charset=utf-8"),
];

/// The embedded file at `path` and its MIME type.
pub fn find(path: &str) -> Option<(&'static str, &'static str)> {
    ASSETS
        .iter()
        .find(|(p, _, _)| *p == path)
        .map(|&(_, body, mime)| (body, mime))
}

#[cfg(test)]
mod tests {
    #[test]
    fn only_embedded_files_are_found() {
        assert!(super::find("index.html").unwrap().0.contains("<canvas"));
        assert!(super::find("vendor/three/LICENSE").unwrap().0.contains("MIT"));
        for bad in ["../Cargo.toml", "/etc/passwd", "vendor/../index.html", ""] {
            assert!(super::find(bad).is_none(), "{bad}");
        }
    }
}
