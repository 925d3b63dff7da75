"""STAG scalable tactile glove: readout driver, frame processing and perception networks."""
