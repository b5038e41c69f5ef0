"""The paper's two-party touch vocabulary: touch events in, answers out."""
