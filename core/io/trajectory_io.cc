// trajectory_io: filled in by the foundation work
