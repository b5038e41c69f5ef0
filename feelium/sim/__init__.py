"""Scene simulator: what the blimp's sensors would see, with ground truth."""
