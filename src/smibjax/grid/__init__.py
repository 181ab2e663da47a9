"""Multi-machine power systems as data (PSS/E raw + dyr), their power flow, network
solution and devices, integrated as one jitted, vmappable, differentiable closed loop."""
