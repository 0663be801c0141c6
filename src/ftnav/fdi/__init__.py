"""ftnav.fdi"""
