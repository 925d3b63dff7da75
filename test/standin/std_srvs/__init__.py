"""Test stand-in for the std_srvs interface package (generated from the typestore)."""
