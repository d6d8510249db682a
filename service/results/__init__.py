"""What a succeeded job produced, for the API: its rewards (`rewards`), their files (`downloads`), comparisons
(`comparisons`), visits and key states (`key_states`) and the motion readout beside the recordings (`readout`).

Numbers come from the engine's numpy/scipy modules, imported on first use (`engine_modules`); never torch.
"""
