//! The small `index.html` of a bench report folder (`showcase-master bench
//! ... --out DIR`): its plots shown, its tables printed, its data linked,
//! so a report opens in a browser like the demo's.

use crate::plot::escape;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Write `dir/index.html` over the files already in `dir`: every `.svg`
/// as an image, every `.md` as text, every `.json` and `.csv` as a link.
/// Returns its path.
pub fn write_index(dir: &Path, title: &str, machine: &str) -> std::io::Result<PathBuf> {
    let mut files: Vec<String> = std::fs::read_dir(dir)?
        .flatten()
        .filter(|e| e.path().is_file())
        .filter_map(|e| e.file_name().into_string().ok())
        .collect();
    files.sort();
    let with = |ext: &str| -> Vec<&String> {
        files
            .iter()
            .filter(|f| f.ends_with(ext) && f.as_str() != "index.html")
            .collect()
    };
    let mut html = String::new();
    let _ = write!(
        html,
        "<!doctype html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>{0}</title>\
         <style>body{{font-family:sans-serif;margin:2em}}img{{max-width:100%}}\
         pre{{background:#f6f6f6;padding:1em;overflow-x:auto}}</style></head><body>\n\
         <h1>{0}</h1>\n<p>Machine: {1}</p>\n",
        escape(title),
        escape(machine)
    );
    for svg in with(".svg") {
        let _ = writeln!(
            html,
            "<figure><img src=\"{0}\" alt=\"{0}\"><figcaption>{0}</figcaption></figure>",
            escape(svg)
        );
    }
    for md in with(".md") {
        let text = std::fs::read_to_string(dir.join(md))?;
        let _ = writeln!(
            html,
            "<h2>{}</h2>\n<pre>{}</pre>",
            escape(md),
            escape(&text)
        );
    }
    let data: Vec<String> = [".json", ".csv"]
        .iter()
        .flat_map(|ext| with(ext))
        .map(|f| format!("<li><a href=\"{0}\">{0}</a></li>", escape(f)))
        .collect();
    if !data.is_empty() {
        let _ = writeln!(html, "<h2>Data</h2>\n<ul>{}</ul>", data.join(""));
    }
    html.push_str("</body></html>\n");
    let path = dir.join("index.html");
    std::fs::write(&path, html)?;
    Ok(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_index_shows_plots_tables_and_data() {
        let dir = std::env::temp_dir().join(format!("showcase-bench-index-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("error_vs_time.svg"), "<svg/>").unwrap();
        std::fs::write(dir.join("report.md"), "| a < b |").unwrap();
        std::fs::write(dir.join("records.json"), "[]").unwrap();
        let path = write_index(&dir, "bench radiosity", "linux x86_64, 2 cores").unwrap();
        // A second run does not list its own index.
        let path2 = write_index(&dir, "bench radiosity", "linux").unwrap();
        assert_eq!(path, path2);
        let html = std::fs::read_to_string(&path).unwrap();
        assert!(html.contains("<img src=\"error_vs_time.svg\""));
        assert!(html.contains("<pre>| a &lt; b |</pre>"));
        assert!(html.contains("<a href=\"records.json\">"));
        assert!(!html.contains("index.html"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
