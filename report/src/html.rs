//! The HTML of the report pages: escaping and the page's head.

/// `s` as HTML text or attribute value.
pub fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// The start of a report page titled `title` with the heading `heading`: the document head,
/// the tables' style and the opened body.
pub fn page_start(title: &str, heading: &str) -> String {
    format!(
        "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>{}</title>\
         <style>body{{font-family:sans-serif;margin:2em}}table{{border-collapse:collapse}}\
         td,th{{border:1px solid #aaa;padding:2px 8px;text-align:right}}td:first-child,th:first-child{{text-align:left}}</style>\
         </head><body>\n<h1>{}</h1>\n",
        escape(title),
        escape(heading)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn markup_in_text_is_shown_not_run() {
        assert_eq!(
            escape(r#"<script>alert("a & b")</script>"#),
            "&lt;script&gt;alert(&quot;a &amp; b&quot;)&lt;/script&gt;"
        );
        let page = page_start("a <b>", "c & d");
        assert!(page.contains("<title>a &lt;b&gt;</title>") && page.contains("<h1>c &amp; d</h1>"));
        assert!(page.starts_with("<!DOCTYPE html>") && page.ends_with("<body>\n<h1>c &amp; d</h1>\n"));
    }
}
