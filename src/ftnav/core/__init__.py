"""ftnav.core"""
