"""G-code: streaming reader into a columnar move table, writer, and a generator of test prints."""
