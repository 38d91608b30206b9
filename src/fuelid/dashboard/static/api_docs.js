"use strict";
// Swagger UI over the dashboard's own OpenAPI schema (a file, not an inline script: the CSP)
window.ui = SwaggerUIBundle({ url: "/api/openapi.json", dom_id: "#swagger-ui" });
const waitForUi = setInterval(() => {
  if (document.querySelector(".swagger-ui .info")) {
    document.body.dataset.ready = "1";
    clearInterval(waitForUi);
  }
}, 100);
