"""The paper's experiments: reproduce/ runs them and summarises, recording/ scores one run, ros/ records it live."""
