"""What the entry points do before and around their work: command-line checks, progress, summaries."""
