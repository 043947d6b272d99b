"""The ground of the package: the Panda model, postures and surfaces, the jump predictors, the batch
API, the closed-form maximum speed and input validation. It imports nothing above it."""
