int fogmap_service_pch_anchor = 0;
