"""Writing what a run found: `report` (report.json, report.csv, error_vs_time.png), `markdown` (figures and
names as Markdown text), `images` (frames, heat maps, overview sheets as PNG/EXR) and `html` (report.html, the
output folder on one offline page)."""
